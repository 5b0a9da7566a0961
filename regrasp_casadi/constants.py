"""The paper's constants, defined once (Sundaralingam & Hermans, ICRA 2018, §IV); SI units.

Every option default that stands for one of these symbols imports it from here:

    >>> from regrasp_casadi.constants import ETA, ZETA
"""

from __future__ import annotations

__all__ = ["ZETA", "ETA", "BETA", "K_POS", "K_ORIENT", "MU", "SELF_CLEARANCE", "JOINT_TORQUE"]

ZETA = 0.006
"""ζ, threshold on the largest contact error that ends the regrasp, m (paper: 6 mm)."""

ETA = 0.01
"""η, bound on the fingertip displacement of one finger gait, m (paper: 1 cm)."""

BETA = 0.001
"""β, clearance the hand's non-contact spheres keep from the object, m (paper: 1 mm)."""

K_POS = 1000.0
"""k1, weight of the relaxed-rigidity position term E_pos of OPT2."""

K_ORIENT = 10.0
"""k2, weight of the relaxed-rigidity orientation term E_or of OPT2."""

MU = 0.5
"""μ, Coulomb friction coefficient of the force-closure tests (grasp stability, grasp generation)."""

SELF_CLEARANCE = 0.001
"""Clearance between the collision spheres of different fingers (and a finger and the palm) that OPT1,
OPT2 and grasp generation keep, m (not the paper's: it has no self-collision constraint; 1 mm, like β)."""

JOINT_TORQUE = 0.7
"""Largest torque of an Allegro joint actuator, N·m (the vendor's stated joint torque; not the paper's:
its planner has no force model). The simulation's actuators saturate at it; the planner's gravity
certificates keep each holding finger's joint torques within a fraction of it."""
