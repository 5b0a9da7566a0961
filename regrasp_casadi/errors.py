"""Exception hierarchy of regrasp_casadi: every error a user can cause is a `RegraspError`."""

from __future__ import annotations

__all__ = [
    "RegraspError",
    "ModelError",
    "MeshError",
    "GraspError",
    "ProblemFileError",
    "PlanFormatError",
]


class RegraspError(Exception):
    """Base class of every error raised on purpose by regrasp_casadi."""


class ModelError(RegraspError):
    """A hand model (URDF) that cannot be read or is not supported; the message names file and element."""


class MeshError(RegraspError):
    """An object mesh that cannot be read or repaired; the message names the file and what is wrong."""


class GraspError(RegraspError):
    """A grasp that is not valid for its hand and object (joint count, limits, contacts off the surface)."""


class ProblemFileError(RegraspError):
    """A problem file (YAML) that is missing, malformed or inconsistent; the message names file and key."""


class PlanFormatError(RegraspError):
    """A plan file (JSON) that cannot be read: wrong schema version, missing or malformed fields."""
