"""Stability certificates of the contacts that hold an object: force closure and gravity hold.

Each certificate is a small convex program over point contacts with Coulomb friction (μ per contact; a
sliding finger is a frictionless contact, normal force only), solved independently of the planner's
smooth models. Pure numpy/scipy (HiGHS) and, when installed, Clarabel (exact second-order cones).

- *force closure* (`force_closure_certificate`): the contacts resist every wrench. The margin is the
  Ferrari–Canny ε (`stability.force_closure_quality`); the verdict is an LP that agrees with it: for
  each of the 12 ± unit wrench directions d_k, the largest s_k such that s_k·d_k is a convex combination
  of the primitive wrenches (unit total normal force). min_k s_k > 0 ⇔ force closure, and
  min_k s_k / √6 ≤ ε ≤ min_k s_k.
- *gravity hold* (`gravity_certificate`): contact forces inside the friction cones, each normal force
  ≤ `max_normal_force`, balance the weight m·g. The margin is the largest scale s of the weight that
  can be held (held ⇔ s ≥ 1); the forces are the least-norm ones (min Σ‖f_i‖²) for the weight itself.

    >>> cert = certify_step(contacts_object, normals_object, holding_mask, "gravity", mu=0.5,
    ...                     mass=0.2, gravity_object=R_palm_object.T @ [0, 0, -9.81], center=com)
    >>> cert.ok, cert.margin, cert.forces            # forces (m, 3), N, object frame; zero rows: not holding
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.constants import MU
from regrasp_casadi.stability import (
    FRICTION_EDGES,
    contact_mu,
    contact_normals,
    ferrari_canny,
    primitive_wrenches,
    tangent_basis,
    torque_reference,
    torque_scale,
)

__all__ = [
    "Certificate", "GRAVITY", "MAX_NORMAL_FORCE", "DENSITY", "FORCE_CLOSURE_TOL", "YCB_MASSES",
    "object_mass", "force_closure_lp_margin", "force_closure_certificate", "GravityHold",
    "gravity_certificate", "certify_step", "step_certificates",
]

GRAVITY = 9.81
"""Standard gravity, m/s²."""
MAX_NORMAL_FORCE = 10.0
"""Default bound on each contact's normal force, N."""
DENSITY = 500.0
"""Default object density, kg/m³ (mass = mesh volume × density when no mass is given)."""
FORCE_CLOSURE_TOL = 1e-6
"""The force-closure LP's margin min_k s_k must exceed this (above HiGHS's feasibility tolerance)."""
YCB_MASSES = {
    "001_chips_can": 0.205,
    "004_sugar_box": 0.514,
    "006_mustard_bottle": 0.603,
    "011_banana": 0.066,
    "021_bleach_cleanser": 1.131,
}
"""Published masses of the YCB objects of the paper benchmark, kg, by YCB folder name."""

Kind = Literal["force_closure", "gravity"]


@dataclass(frozen=True, eq=False)
class Certificate:
    """The stability certificate of one holding set (e.g. of one plan step)."""

    kind: Kind
    """"force_closure" | "gravity"."""
    ok: bool
    """Whether the holding contacts are certified."""
    margin: float
    """force_closure: Ferrari–Canny ε (> 0 certified); gravity: largest holdable scale s of the weight
    (≥ 1 certified). NaN when the solver failed."""
    forces: NDArray[np.float64] | None
    """gravity, when held: (m, 3) contact forces on the object, object frame, N (least-norm); else None."""
    detail: str
    """Human-readable summary (LP margin, solver, largest normal force, …)."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-native dict (a non-finite margin becomes None)."""
        return {
            "kind": self.kind, "ok": bool(self.ok),
            "margin": float(self.margin) if math.isfinite(self.margin) else None,
            "forces": None if self.forces is None else np.asarray(self.forces, float).tolist(),
            "detail": self.detail,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Certificate:
        """Inverse of `to_dict`."""
        forces = d.get("forces")
        return cls(kind=d["kind"], ok=bool(d["ok"]),
                   margin=float("nan") if d.get("margin") is None else float(d["margin"]),
                   forces=None if forces is None else np.asarray(forces, float).reshape(-1, 3),
                   detail=str(d.get("detail", "")))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Certificate):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def object_mass(mesh: Any, mass: float | None = None, density: float = DENSITY) -> float:
    """The object's mass, kg: `mass` when given, else the volume of `mesh` (a watertight trimesh, m³)
    × `density` (kg/m³)."""
    value = float(mass) if mass is not None else abs(float(mesh.volume)) * float(density)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"object mass must be > 0 kg, got {value} (mass={mass}, density={density})")
    return value


# ------------------------------------------------------------------------------------ force closure
def force_closure_lp_margin(W: NDArray[np.float64]) -> float:
    """min over the 12 ± unit wrench directions d_k of the largest s_k with s_k·d_k = Σ λ_j w_j,
    λ ≥ 0, Σ λ_j ≤ 1 (one LP, HiGHS), for primitive wrenches W (k, 6) (`stability.primitive_wrenches`).
    > 0 ⇔ force closure."""
    from scipy.optimize import linprog
    from scipy.sparse import block_diag, csr_matrix, hstack

    if len(W) == 0:
        return 0.0
    k = len(W)
    D = np.vstack([np.eye(6), -np.eye(6)])  # (12, 6) directions
    # variables: λ^1..λ^12 (k each), t; maximise t s.t. Wᵀλ^d − t·d = 0, Σλ^d ≤ 1, λ ≥ 0
    A_eq = hstack([block_diag([W.T] * 12), csr_matrix(-D.reshape(72, 1))]).tocsr()
    A_ub = hstack([block_diag([np.ones((1, k))] * 12), csr_matrix((12, 1))]).tocsr()
    c = np.zeros(12 * k + 1)
    c[-1] = -1.0
    res = linprog(c, A_ub=A_ub, b_ub=np.ones(12), A_eq=A_eq, b_eq=np.zeros(72),
                  bounds=(0, None), method="highs")
    if res.status != 0:
        return float("nan")
    return float(max(-res.fun, 0.0))


def force_closure_certificate(
    contacts: NDArray[np.float64],
    normals: NDArray[np.float64],
    mu: float | NDArray[np.float64] = MU,
    center: NDArray[np.float64] | None = None,
    length: float | None = None,
    sliding: NDArray[np.bool_] | None = None,
    n_edges: int = FRICTION_EDGES,
) -> Certificate:
    """Force-closure certificate of k contacts (k, 3) with outward normals (k, 3), object frame, m.

    ok ⇔ the LP margin (`force_closure_lp_margin`) exceeds `FORCE_CLOSURE_TOL`; margin = ε
    (`stability.ferrari_canny`), both of the same primitive wrenches (torques about `center` scaled by
    `length`). `mu` is a scalar or
    (k,); contacts where `sliding` (k,) is True are frictionless. forces is None.
    """
    c = np.asarray(contacts, float).reshape(-1, 3)
    if len(c) == 0:
        return Certificate("force_closure", False, 0.0, None, "no holding contacts")
    mu_i = contact_mu(mu, len(c), sliding)
    center, length = torque_scale(c, center, length)
    W = primitive_wrenches(c, normals, mu_i, center, length, n_edges)
    eps, s = ferrari_canny(W), force_closure_lp_margin(W)
    ok = bool(s > FORCE_CLOSURE_TOL)
    n_slide = int(np.sum(mu_i == 0))
    detail = (f"{'force closure' if ok else 'no force closure'} of {len(c)} contacts"
              f"{f' ({n_slide} frictionless)' if n_slide else ''}: LP margin {s:.3g}, ε {eps:.3g}")
    return Certificate("force_closure", ok, eps, None, detail)


# ------------------------------------------------------------------------------------ gravity hold
def _equilibrium_rows(contacts, center, length) -> NDArray[np.float64]:
    """(6, 3k) map from stacked contact forces to [Σ f_i; Σ (c_i − center) × f_i / L]."""
    G = np.zeros((6, 3 * len(contacts)))
    for i, r in enumerate(np.asarray(contacts, float) - center):
        G[:3, 3 * i:3 * i + 3] = np.eye(3)
        G[3:, 3 * i:3 * i + 3] = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]) / length
    return G


def _force_basis(normals, mu_i) -> tuple[NDArray[np.float64], list[int]]:
    """(3k, v) map from local force variables to stacked forces: (a, u, v) ↦ −a n + u t1 + v t2 for a
    frictional contact, a ↦ −a n for a frictionless one; and the column of each contact's normal force a."""
    cols, a_col, blocks = 0, [], []
    for ni, mui in zip(normals, mu_i, strict=True):
        t1, t2 = tangent_basis(ni)
        blocks.append(np.column_stack([-ni, t1, t2]) if mui > 0 else -ni.reshape(3, 1))
        a_col.append(cols)
        cols += blocks[-1].shape[1]
    B = np.zeros((3 * len(blocks), cols))
    for i, (b, j) in enumerate(zip(blocks, a_col, strict=True)):
        B[3 * i:3 * i + 3, j:j + b.shape[1]] = b
    return B, a_col


@dataclass(frozen=True, eq=False)
class GravityHold:
    """A gravity hold to certify: k point contacts with Coulomb friction (μ_i = 0 where sliding) and a
    bound on each normal force, holding the object's weight. The arrays are stored as float (normals
    made unit, contacts and normals (k, 3)).

        >>> hold = GravityHold(contacts, normals, weight=mass * g_object, center=com, mu=0.5)
        >>> cert = gravity_certificate(hold)
        >>> hold.violation(cert.forces)          # ≈ 0: the forces are a checkable certificate
    """

    contacts: NDArray[np.float64]
    """(k, 3) contact points, object frame, m."""
    normals: NDArray[np.float64]
    """(k, 3) outward unit surface normals, object frame."""
    weight: NDArray[np.float64]
    """(3,) the object's weight m·g, object frame, N (non-zero)."""
    center: NDArray[np.float64]
    """(3,) the object's centre of mass, object frame, m."""
    mu: float | NDArray[np.float64] = MU
    """Friction coefficient, scalar or (k,)."""
    max_normal_force: float = MAX_NORMAL_FORCE
    """Bound on each normal force, N."""
    sliding: NDArray[np.bool_] | None = None
    """(k,) bool, contacts that slide (frictionless)."""
    min_normal_force: float = 0.0
    """Least normal force of every contact in the forces that hold the weight itself, N (a reserve: a
    contact that carries almost nothing is lost to the least disturbance; the weight scale s of the
    margin is computed without it)."""
    torque_maps: NDArray[np.float64] | None = None
    """(k, J, 3) joint torques of each contact's finger per newton of its force on the object (object
    frame), N·m/N: τ_i = M_i f_i = J_iᵀ R_palm_object f_i for the tip Jacobian J_i (J joints; rows of
    fingers with fewer joints zero). None: no torque bound."""
    max_joint_torque: float = math.inf
    """Bound on every |τ_ij| of `torque_maps`, N·m (holds the weight scale s of the margin too)."""

    def __post_init__(self) -> None:
        weight = np.asarray(self.weight, float).reshape(3)
        if not np.linalg.norm(weight) > 0:
            raise ValueError(f"weight must be a non-zero force (N), got {weight}")
        n = np.asarray(self.normals, float).reshape(-1, 3)
        object.__setattr__(self, "contacts", np.asarray(self.contacts, float).reshape(-1, 3))
        object.__setattr__(self, "normals", n / np.linalg.norm(n, axis=1, keepdims=True))
        object.__setattr__(self, "weight", weight)
        object.__setattr__(self, "center", np.asarray(self.center, float).reshape(3))
        if self.torque_maps is not None:
            M = np.asarray(self.torque_maps, float)
            if M.ndim != 3 or M.shape[0] != len(self.contacts) or M.shape[2] != 3:
                raise ValueError(f"torque_maps must be (k, J, 3) for k = {len(self.contacts)} contacts, "
                                 f"got shape {M.shape}")
            object.__setattr__(self, "torque_maps", M)

    @property
    def torque_bounded(self) -> bool:
        """Whether the joint torques are bounded (`torque_maps` given, finite `max_joint_torque`)."""
        return self.torque_maps is not None and math.isfinite(self.max_joint_torque)

    def joint_torques(self, forces: NDArray[np.float64]) -> NDArray[np.float64]:
        """(k, J) joint torques of `forces` (k, 3), N·m (zeros without `torque_maps`)."""
        f = np.asarray(forces, float).reshape(-1, 3)
        if self.torque_maps is None:
            return np.zeros((len(f), 1))
        return np.einsum("kjd,kd->kj", self.torque_maps, f)

    @property
    def mu_i(self) -> NDArray[np.float64]:
        """(k,) friction coefficient of each contact (0 where sliding)."""
        return contact_mu(self.mu, len(self.contacts), self.sliding)

    @property
    def wrench(self) -> NDArray[np.float64]:
        """(6,) the wrench the contacts must balance: the weight, no torque about `center`."""
        return np.concatenate([self.weight, np.zeros(3)])

    def violation(self, forces: NDArray[np.float64]) -> float:
        """Largest violation by `forces` (k, 3), N, of this hold: force and torque balance (N, N·m),
        negative or excessive normal force (N) and friction-cone excess (N). Independent of the solver:
        checks a stored certificate."""
        c, n, f = self.contacts, self.normals, np.asarray(forces, float).reshape(-1, 3)
        a = -np.sum(f * n, axis=1)
        tangential = np.linalg.norm(f + a[:, None] * n, axis=1)
        return float(max(
            np.max(np.abs(f.sum(axis=0) + self.weight)),
            np.max(np.abs(np.cross(c - self.center, f).sum(axis=0))),
            np.max(self.min_normal_force - a), np.max(a - self.max_normal_force),
            np.max(tangential - self.mu_i * a),
            np.max(np.abs(self.joint_torques(f))) - self.max_joint_torque,
        ))

    def torque_rows(self, F: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rows (A, b) of |τ_ij| ≤ max_joint_torque, A x ≤ b, for stacked forces F x (F (3k, v)); empty
        without a torque bound."""
        if not self.torque_bounded:
            return np.zeros((0, F.shape[1])), np.zeros(0)
        rows = [self.torque_maps[i] @ F[3 * i:3 * i + 3] for i in range(len(self.contacts))]
        T = np.vstack(rows)
        T = T[np.abs(T).max(axis=1) > 0]
        A = np.vstack([T, -T])
        return A, np.full(len(A), float(self.max_joint_torque))


def _socp_hold(hold: GravityHold, E, B, a_col, scale_free: bool):
    """Clarabel: forces x (local variables) with E B x + s·wrench = 0 (scale_free: maximise s ≥ 0,
    0 ≤ a_i ≤ f_max) or E B x = −wrench (minimise ‖x‖², f_min ≤ a_i ≤ f_max), (μ_i a_i, u_i, v_i) ∈ SOC₃,
    and |M_i (B x)_i| ≤ τ_max with a torque bound. -> (x, s) or None."""
    mu_i, wrench, f_max = hold.mu_i, hold.wrench, float(hold.max_normal_force)
    f_min = 0.0 if scale_free else float(hold.min_normal_force)
    import clarabel
    from scipy import sparse

    nv = B.shape[1] + int(scale_free)
    rows, b, cones = [], [], []
    eq = np.hstack([E @ B, wrench.reshape(6, 1)]) if scale_free else E @ B
    rows.append(eq)
    b.append(np.zeros(6) if scale_free else -wrench)
    cones.append(clarabel.ZeroConeT(6))
    nonneg = []
    for j in a_col:
        lo, hi = np.zeros(nv), np.zeros(nv)
        lo[j], hi[j] = -1.0, 1.0
        nonneg += [(lo, -f_min), (hi, f_max)]
    if scale_free:
        e = np.zeros(nv)
        e[-1] = -1.0
        nonneg.append((e, 0.0))
    A_tau, b_tau = hold.torque_rows(B)  # |τ| ≤ τ_max, on the forces B x
    nonneg += [(np.concatenate([r, np.zeros(nv - B.shape[1])]), v) for r, v in zip(A_tau, b_tau, strict=True)]
    rows.append(np.array([r for r, _ in nonneg]))
    b.append(np.array([v for _, v in nonneg]))
    cones.append(clarabel.NonnegativeConeT(len(nonneg)))
    for j, mui in zip(a_col, mu_i, strict=True):
        if mui > 0:
            S = np.zeros((3, nv))
            S[0, j], S[1, j + 1], S[2, j + 2] = -mui, -1.0, -1.0
            rows.append(S)
            b.append(np.zeros(3))
            cones.append(clarabel.SecondOrderConeT(3))
    q = np.zeros(nv)
    if scale_free:
        q[-1] = -1.0
        P = sparse.csc_matrix((nv, nv))
    else:
        P = sparse.identity(nv, format="csc") * 2.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    sol = clarabel.DefaultSolver(P, q, sparse.csc_matrix(np.vstack(rows)), np.concatenate(b), cones,
                                 settings).solve()
    if sol.status != clarabel.SolverStatus.Solved:
        return None
    x = np.asarray(sol.x, float)
    return (x[:-1], float(x[-1])) if scale_free else (x, 1.0)


def _lp_hold(hold: GravityHold, E, length, n_edges, scale_free: bool):
    """HiGHS fallback with inscribed linearised cones: forces Σ_j β_ij e_ij (β ≥ 0, e_ij the edges of
    unit normal force), Σ_j β_ij ≤ f_max, joint torques within the bound; maximise s (scale_free) or
    minimise the largest normal force for the weight itself, with Σ_j β_ij ≥ f_min. -> (stacked forces
    (3k,), s) or None."""
    normals, contacts, mu_i = hold.normals, hold.contacts, hold.mu_i
    center, wrench, f_max = hold.center, hold.wrench, float(hold.max_normal_force)
    from scipy.optimize import linprog

    edges, owner = [], []
    for i, (ni, mui) in enumerate(zip(normals, mu_i, strict=True)):
        w = primitive_wrenches(contacts[i:i + 1], ni.reshape(1, 3), mui, center, length, n_edges)
        edges += list(w[:, :3])
        owner += [i] * len(w)
    F = np.zeros((3 * len(normals), len(edges)))
    for j, (e, i) in enumerate(zip(edges, owner, strict=True)):
        F[3 * i:3 * i + 3, j] = e
    k, ne = len(normals), len(edges)
    A_ub = np.zeros((k, ne + 1))  # per-contact normal force Σ_j β_ij; last column: s or z
    A_ub[owner, np.arange(ne)] = 1.0
    c = np.zeros(ne + 1)
    if scale_free:  # maximise s: E F β + s·wrench = 0, Σ_j β_ij ≤ f_max
        A_eq, b_eq, b_ub = np.hstack([E @ F, wrench.reshape(6, 1)]), np.zeros(6), np.full(k, f_max)
        c[-1] = -1.0
        bounds = [(0, None)] * (ne + 1)
    else:  # minimise z: E F β = −wrench, Σ_j β_ij ≤ z ≤ f_max
        A_eq, b_eq, b_ub = np.hstack([E @ F, np.zeros((6, 1))]), -wrench, np.zeros(k)
        A_ub[:, -1] = -1.0
        if hold.min_normal_force > 0:  # −Σ_j β_ij ≤ −f_min
            A_low = np.zeros((k, ne + 1))
            A_low[owner, np.arange(ne)] = -1.0
            A_ub = np.vstack([A_ub, A_low])
            b_ub = np.concatenate([b_ub, np.full(k, -float(hold.min_normal_force))])
        c[-1] = 1.0
        bounds = [(0, None)] * ne + [(0, f_max)]
    A_tau, b_tau = hold.torque_rows(F)  # |τ| ≤ τ_max, on the forces F β
    if len(A_tau):
        A_ub = np.vstack([A_ub, np.hstack([A_tau, np.zeros((len(A_tau), 1))])])
        b_ub = np.concatenate([b_ub, b_tau])
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs")
    if res.status != 0:
        return None
    return F @ res.x[:-1], (float(res.x[-1]) + 0.0 if scale_free else 1.0)


def gravity_certificate(hold: GravityHold, solver: Literal["auto", "socp", "lp"] = "auto",
                        n_edges: int = FRICTION_EDGES) -> Certificate:
    """Gravity-hold certificate: can the contacts of `hold` hold its weight?

    Finds contact forces f_i (on the object) with normal force a_i = −f_i·n_i ∈ [0, max_normal_force],
    tangential part ‖f_i + a_i n_i‖ ≤ μ_i a_i, Σ f_i + weight = 0 and Σ (c_i − center) × f_i = 0, and,
    with `hold.torque_maps`, every joint torque |M_i f_i| ≤ max_joint_torque.
    margin = the largest s for which s·weight can be held (held ⇔ s ≥ 1); forces = the least-norm
    forces (min Σ‖f_i‖²) for the weight itself, (k, 3), N, object frame, each normal force at least
    `min_normal_force` (held ⇔ s ≥ 1 and such forces exist).

    Args:
        hold: the contacts, friction, weight and force bound.
        solver: "socp" (Clarabel, exact cones), "lp" (HiGHS, `n_edges`-edge inscribed cones: conservative;
            its forces minimise the largest normal force instead), "auto" (socp when clarabel imports).
    """
    c = hold.contacts
    if len(c) == 0:
        return Certificate("gravity", False, 0.0, None, "no holding contacts")
    if solver == "auto":
        try:
            import clarabel  # noqa: F401

            solver = "socp"
        except ImportError:
            solver = "lp"
    _, length = torque_scale(c, hold.center, None)
    E = _equilibrium_rows(c, hold.center, length)
    if solver == "socp":
        B, a_col = _force_basis(hold.normals, hold.mu_i)

        def program(scale_free: bool):  # -> (stacked forces (3k,), s) or None
            res = _socp_hold(hold, E, B, a_col, scale_free)
            return None if res is None else (B @ res[0], res[1])
    elif solver == "lp":
        program = functools.partial(_lp_hold, hold, E, length, n_edges)
    else:
        raise ValueError(f"solver: expected 'auto', 'socp' or 'lp', got {solver!r}")
    best = program(scale_free=True)
    held = program(scale_free=False) if best and best[1] >= 1 else None
    s = float("nan") if best is None else best[1]
    forces = None if held is None else held[0].reshape(-1, 3)
    ok = forces is not None
    w = float(np.linalg.norm(hold.weight))
    detail = f"{'holds' if ok else 'cannot hold'} {w:.3g} N with {len(c)} contacts ({solver}): scale {s:.3g}"
    if hold.torque_bounded:
        detail += f" (joint torques ≤ {hold.max_joint_torque:.3g} N·m)"
    if ok:
        a = -np.sum(forces * hold.normals, axis=1)
        detail += f", normal forces {float(np.min(a)):.3g}–{float(np.max(a)):.3g} N"
        if hold.torque_bounded:
            detail += f", largest joint torque {float(np.max(np.abs(hold.joint_torques(forces)))):.3g} N·m"
    elif best and best[1] >= 1:
        detail += f", but not with every normal force ≥ {hold.min_normal_force:g} N"
    return Certificate("gravity", ok, s, forces, detail)


# ------------------------------------------------------------------------------------ plan steps
def certify_step(  # noqa: PLR0913 (the force-closure and the gravity data of a step; knobs keyword-only)
    contacts_object: NDArray[np.float64],
    normals_object: NDArray[np.float64],
    holding_mask: NDArray[np.bool_],
    kind: Kind = "force_closure",
    mu: float | NDArray[np.float64] = MU,
    mass: float | None = None,
    gravity_object: NDArray[np.float64] | None = None,
    *,
    center: NDArray[np.float64] | None = None,
    length: float | None = None,
    sliding: NDArray[np.bool_] | None = None,
    max_normal_force: float = MAX_NORMAL_FORCE,
    min_normal_force: float = 0.0,
    torque_maps: NDArray[np.float64] | None = None,
    max_joint_torque: float = math.inf,
    solver: Literal["auto", "socp", "lp"] = "auto",
) -> Certificate:
    """The certificate of the holding set of one step (for a gait: every finger but the moving one).

    Args:
        contacts_object: (m, 3) contacts of all fingers, object frame, m.
        normals_object: (m, 3) outward unit normals at them, object frame.
        holding_mask: (m,) bool, the fingers that hold the object during the step.
        kind: "force_closure" or "gravity".
        mu: friction coefficient, scalar or (m,).
        mass: the object's mass, kg (gravity).
        gravity_object: (3,) gravitational acceleration in the object frame, m/s² (gravity), e.g.
            R_palm_objectᵀ (0, 0, −9.81) for gravity along −z of the palm.
        center: (3,) object frame, m: torque reference (force closure; default the holding contacts'
            mean), the centre of mass (gravity: required).
        length: torque scale L of ε, m (force closure; default the contacts' largest distance from center).
        sliding: (m,) bool, fingers that slide (frictionless contacts).
        max_normal_force: bound on each normal force, N (gravity).
        min_normal_force: least normal force of every holding contact in the forces that hold the
            weight, N (gravity; `GravityHold.min_normal_force`).
        torque_maps: (m, J, 3) joint torques of each finger per newton of its force on the object, N·m/N
            (gravity; `GravityHold.torque_maps`), None: no torque bound; max_joint_torque: N·m.
        solver: see `gravity_certificate`.

    Returns:
        The Certificate; for gravity its forces are (m, 3) rows in the input order, zero where not holding.
    """
    c = np.asarray(contacts_object, float).reshape(-1, 3)
    n = np.asarray(normals_object, float).reshape(-1, 3)
    holding = np.broadcast_to(np.asarray(holding_mask, bool), (len(c),))
    mu_i = contact_mu(mu, len(c), sliding)[holding]
    if kind == "force_closure":
        return force_closure_certificate(c[holding], n[holding], mu_i, center, length)
    if kind != "gravity":
        raise ValueError(f"kind: expected 'force_closure' or 'gravity', got {kind!r}")
    if mass is None or gravity_object is None or center is None:
        raise ValueError("a gravity certificate needs mass (kg), gravity_object (m/s²) and center (COM)")
    weight = float(mass) * np.asarray(gravity_object, float).reshape(3)
    maps = None if torque_maps is None else np.asarray(torque_maps, float)[holding]
    cert = gravity_certificate(GravityHold(c[holding], n[holding], weight, center, mu_i, max_normal_force,
                                           min_normal_force=min_normal_force, torque_maps=maps,
                                           max_joint_torque=max_joint_torque), solver)
    if cert.forces is None:
        return cert
    forces = np.zeros((len(c), 3))
    forces[holding] = cert.forces
    return Certificate(cert.kind, cert.ok, cert.margin, forces, cert.detail)


def step_certificates(
    plan: Any,
    obj: Any | None,
    kind: Kind = "force_closure",
    mu: float = MU,
    *,
    hand: Any = None,
    mass: float | None = None,
    density: float = DENSITY,
    gravity_palm: NDArray[np.float64] = (0.0, 0.0, -GRAVITY),
    max_normal_force: float = MAX_NORMAL_FORCE,
    solver: Literal["auto", "socp", "lp"] = "auto",
) -> list[Certificate]:
    """The certificate of every step of a plan, from its data and the object's exact mesh.

    A gait step's holding set is every finger but the moving one, in the grasp it lifts from (the
    previous step); any other step's is every finger in the step's own grasp. Contacts are the plan's
    `contacts_object`; normals point from them to the tip-sphere centres (`hand.tip_positions(q)` mapped
    by the step's T_palm_object). Torques are taken about the mesh's centre of mass, ε scaled by its
    largest vertex distance (`stability.torque_reference`); the mass is `mass` or the mesh volume ×
    `density`; gravity is `gravity_palm` (3,), m/s², palm frame.

    Args:
        plan: a `Plan`; obj, hand: its object model (with `.mesh`) and hand (None: rebuilt from the
            plan's specs by `problem.plan_models`).
    Returns:
        One Certificate per step, `plan.steps` order.
    """
    if hand is None or obj is None:
        from regrasp_casadi.problem import plan_models  # imports casadi: only when a model is missing

        hand, obj = plan_models(plan, hand, obj)
    com, length = torque_reference(obj.mesh)
    m_kg = object_mass(obj.mesh, mass, density) if kind == "gravity" else None
    fingers = list(plan.fingers)
    certs = []
    for k, step in enumerate(plan.steps):
        gait = step.kind == "gait" and k > 0
        at = plan.steps[k - 1] if gait else step
        R, p = at.T_palm_object[:3, :3], at.T_palm_object[:3, 3]
        tips_object = (np.asarray(hand.tip_positions(at.q), float).reshape(-1, 3) - p) @ R
        normals = contact_normals(at.contacts_object, tips_object)
        holding = np.array([not (gait and f == step.finger) for f in fingers])
        certs.append(certify_step(at.contacts_object, normals, holding, kind, mu, m_kg,
                                  R.T @ np.asarray(gravity_palm, float), center=com, length=length,
                                  max_normal_force=max_normal_force, solver=solver))
    return certs
