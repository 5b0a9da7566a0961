"""The MuJoCo model of a hand holding an object, built with `mujoco.MjSpec` from the project's own data.

No XML file is written or read: the hand's kinematic tree comes from its URDF (read with yourdfpy from
``hand.urdf_path``), its collision geometry from ``hand.spheres`` (the sphere cover and the fingertip
contact spheres, exactly the planner's collision model) or, when the URDF has ``<collision>`` elements,
from those and the tip spheres (`SimOptions.hand_collision`), and the object from its convex pieces
(``obj.pieces[i].vertices``, object frame, m). Every physical constant is a field of `SimOptions`.

World frame: the palm is fixed in the world at the origin, ``R_world_palm = quat(options.palm_wxyz)``;
gravity is ``R_world_palm @ options.gravity_palm``. Every body of the model is named after its URDF
link; the object body is ``"object"`` (a free joint ``"object_free"``).

    >>> built = build_model(hand, obj, SimOptions())
    >>> model = built.model        # mujoco.MjModel; built.qpos_hand (n,) qpos addresses in q order
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from regrasp_casadi.constants import JOINT_TORQUE
from regrasp_casadi.errors import ModelError

__all__ = ["SimOptions", "SimModel", "build_model", "object_inertia", "OBJECT_BODY"]

OBJECT_BODY = "object"
"""Name of the object's free body in the MuJoCo model."""

_INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}
_HAND_GROUP, _OBJECT_GROUP = 1, 2  # contype / conaffinity bits
_TOKEN_MASS = 1e-3  # kg, of a link without collision geometry (MuJoCo needs a mass; gravity-compensated)


@dataclass(frozen=True)
class SimOptions:
    """Every physical and execution constant of `regrasp_casadi.simulate` (SI units)."""

    # ---- physics engine
    timestep: float = 1e-3
    """Simulation time step, s."""
    integrator: str = "implicitfast"
    """MuJoCo integrator: "implicitfast" | "implicit" | "euler" | "rk4"."""
    cone: str = "elliptic"
    """Friction cone: "elliptic" | "pyramidal"."""
    impratio: float = 10.0
    """Ratio of frictional to normal constraint impedance (> 1 reduces slip with elliptic cones), -."""
    solver_iterations: int = 100
    """Constraint solver iterations per step."""
    friction: float = 0.5
    """Sliding friction coefficient μ of every hand-object contact, -."""
    torsional_friction: float = 0.0
    """Torsional friction coefficient, m (used only when condim >= 4)."""
    condim: int = 3
    """Contact dimensionality: 3 = point contact with friction (the planner's and verify's model), 4 adds
    torsional friction, 6 rolling."""
    solref: tuple[float, float] = (0.004, 1.0)
    """Contact solver reference (time constant s, damping ratio -): contact stiffness."""
    solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 1e-3, 0.5, 2.0)
    """Contact solver impedance (dmin -, dmax -, width m, midpoint -, power -)."""
    # ---- hand
    palm_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Orientation of the palm frame in the world frame, unit quaternion (w, x, y, z)."""
    gravity_palm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Gravity in the PALM frame, m/s² (zero: gravity off; (0, 0, -9.81): along −z of the palm). The
    hand's links are gravity-compensated (as the Allegro's own controller does)."""
    kp: float = 3.0
    """Position-actuator gain (stiffness) of every joint, N·m/rad."""
    kv: float = 0.1
    """Position-actuator damping of every joint, N·m·s/rad."""
    force_limit: float = JOINT_TORQUE
    """Torque limit of every actuator, N·m (the Allegro's stated joint torque)."""
    joint_damping: float = 0.02
    """Passive viscous damping of every joint, N·m·s/rad."""
    armature: float = 1e-4
    """Rotor inertia added to every joint, kg·m²."""
    hand_density: float = 1000.0
    """Density of the hand's collision spheres, kg/m³ (the links' mass and inertia come from them)."""
    hand_collision: str = "spheres"
    """Collision geometry of the hand's links besides the fingertip contact spheres (always the planner's
    tip spheres): "spheres" (default) the sphere cover (`hand.spheres`, the planner's collision model);
    "urdf" the URDF's own ``<collision>`` elements (box, cylinder, sphere, mesh: the convex hull of the
    mesh file), those of the links carrying a tip sphere left out (ModelError when there are none);
    "auto": "urdf" when some link of the URDF has a collision element, else "spheres". (The shipped
    Allegro URDF's collision elements are its sphere cover; the vendor URDF's are boxes and spheres.)"""
    hand_self_collision: bool = False
    """False: hand bodies never collide with each other (the planner does not model it, and the
    conservative sphere covers of neighbouring fingers overlap by up to 30 mm in planned grasps). True:
    they do, except bodies of the same finger and adjacent links (always excluded)."""
    # ---- object
    object_mass: float | None = None
    """Object mass, kg; None: mesh volume × `object_density`."""
    object_density: float = 500.0
    """Object density used when `object_mass` is None, kg/m³."""
    # ---- execution (see regrasp_casadi.sim_control)
    grip: str = "balanced"
    """How touching fingertips press: "balanced" (forces from a linear program that cancel gravity's
    wrench, normal ≥ `grip_force`, applied as joint offsets Jᵀf/kp) or "squeeze" (each tip commanded
    `squeeze_depth` into the surface along its contact normal)."""
    surface_correction: bool = True
    """Command each touching tip onto the SIMULATED object's surface: the object's convex pieces may
    over-cover (or under-cover) the mesh the planner used by a few mm where a finger touches, so the tip
    target moves along the contact normal by the difference (`simulate.surface_distances`, measured per
    step with MuJoCo's signed distance, interpolated between steps). False: the plan's tip positions."""
    grip_force: float = 1.0
    """Smallest normal force of a holding fingertip ("balanced" grip), N."""
    grip_friction_fraction: float = 0.8
    """Fraction of `friction` the "balanced" grip may use for tangential forces, -."""
    squeeze_depth: float = 2e-3
    """How far each holding fingertip is commanded INTO the surface along the contact normal ("squeeze"
    grip), m."""
    lift_height: float = 5e-3
    """Peak height above the surface of a gait finger's tip in mid-move, m."""
    unload_fraction: float = 0.2
    """Fraction of a gait step spent handing the moving finger's load to the others (and, at the end,
    taking it back) while its joints stay, -."""
    min_handover_time: float = 0.1
    """Shortest load hand-over of a gait or slide step, s: such a step lasts at least
    min_handover_time / unload_fraction (a sudden change of the grip forces shakes the object)."""
    slide_drag: bool = False
    """True: the grip of a slide step plans for the sliding finger's Coulomb kinetic friction, its force
    on the object f_n (−n + μ ŝ) (ŝ its motion over the object), balanced by the other fingers, the
    LP's residual reporting what they cannot balance. False (default): the slider pushes along its
    normal only. MuJoCo's friction is a soft constraint that lets a slow slide creep below μ f_n, so the
    full feed-forward pushes the object (measured: tests/data/box_rotate_frictionless_slide.json, 2.83
    mm with it, 0.08 mm without)."""
    feedback: str = "object_pose"
    """Execution loop: "object_pose" closes it on the object's pose (an exact tracker; each holding tip
    moves by the rigid correction that takes the simulated object onto the plan, integrated, see
    `sim_feedback`); "none": open loop, the plan's joints and grip only."""
    feedback_gain: float = 10.0
    """Integral gain k_I of the object-pose feedback, 1/s."""
    feedback_limit: float = 0.01
    """Largest tip displacement of one finger's feedback offset, m."""
    force_gain: float = 3.0
    """Integral gain k_F of the grip-force feedback, 1/s (`sim_grip_feedback`: each holding tip's normal
    force driven to the "balanced" grip's, from MuJoCo's contact forces); 0: off (the grip feed-forward
    only)."""
    force_limit_offset: float = 0.005
    """Largest tip displacement of one finger's grip-force feedback offset, m."""
    settle_time: float = 0.5
    """Time spent at the plan's first step before the motion starts, s (squeeze and gravity ramp in
    over its first 60 %)."""
    hold_time: float = 0.5
    """Time spent at the plan's last step after the motion, s."""
    joint_velocity: float = 1.0
    """Joint speed of the interpolated motion between two steps, rad/s."""
    min_step_duration: float = 0.2
    """Shortest duration of one step's motion, s."""
    record_dt: float = 0.01
    """Sampling period of the recorded time series, s."""
    # ---- judgement
    drop_distance: float = 0.02
    """Object position deviation above which the object counts as dropped, m."""
    min_fingers: int = 2
    """Fewest fingers touching the object at a step end for it to count as held."""
    touch_window: float = 0.02
    """A finger touches the object at a step end when it touched it at some instant of the last
    `touch_window` s, s."""
    tol_position: float = 5e-3
    """Largest step-end position deviation (object centre of mass) for the plan to count as followed, m."""
    tol_rotation: float = 5.0
    """Largest step-end rotation deviation for the plan to count as followed, degrees."""
    tol_tip_drift: float = 5e-3
    """Largest step-end distance of a fingertip from where the plan has it on the object (tip centres in
    the object frame, `StepRecord.tip_drift_mm`) for the plan to count as followed, m: an object held at
    its planned pose by fingers that slipped elsewhere on it, or by a finger whose slide did not happen,
    is not the plan executed."""

    def __post_init__(self) -> None:
        if self.integrator not in _INTEGRATORS:
            raise ValueError(f"SimOptions.integrator: {self.integrator!r} not in {tuple(_INTEGRATORS)}")
        if self.cone not in _CONES:
            raise ValueError(f"SimOptions.cone: {self.cone!r} not in {tuple(_CONES)}")
        if self.feedback not in ("none", "object_pose"):
            raise ValueError(f"SimOptions.feedback: {self.feedback!r} not in ('none', 'object_pose')")
        if self.grip not in ("balanced", "squeeze"):
            raise ValueError(f"SimOptions.grip: {self.grip!r} not in ('balanced', 'squeeze')")
        if not 0.0 <= self.unload_fraction < 0.5:
            raise ValueError(f"SimOptions.unload_fraction must be in [0, 0.5), got {self.unload_fraction}")
        if self.hand_collision not in ("auto", "spheres", "urdf"):
            raise ValueError(f"SimOptions.hand_collision: {self.hand_collision!r} not in ('auto', 'spheres', "
                             "'urdf')")
        if self.condim not in (1, 3, 4, 6):
            raise ValueError(f"SimOptions.condim: {self.condim} not in (1, 3, 4, 6)")
        for name in ("timestep", "kp", "force_limit", "object_density", "joint_velocity", "record_dt"):
            if not getattr(self, name) > 0:
                raise ValueError(f"SimOptions.{name} must be > 0, got {getattr(self, name)}")
        if self.object_mass is not None and not self.object_mass > 0:
            raise ValueError(f"SimOptions.object_mass must be > 0, got {self.object_mass}")

    @property
    def R_world_palm(self) -> NDArray[np.float64]:
        """(3, 3) rotation of the palm frame in the world frame."""
        quat = np.asarray(self.palm_wxyz, dtype=float)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, quat / np.linalg.norm(quat))
        return R.reshape(3, 3)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every field."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


@dataclass
class SimModel:
    """A compiled model and the indices that map it to the project's hand and object."""

    model: mujoco.MjModel
    """The compiled MuJoCo model."""
    spec: mujoco.MjSpec
    """The spec it was compiled from (keep it alive with the model)."""
    qpos_hand: NDArray[np.int64]
    """(n,) qpos address of each actuated joint, `hand.joint_names` order."""
    dof_hand: NDArray[np.int64]
    """(n,) dof address of each actuated joint."""
    actuator: NDArray[np.int64]
    """(n,) actuator id of each actuated joint."""
    object_body: int
    """Body id of the object."""
    qpos_object: int
    """qpos address of the object's free joint (3 position + 4 quaternion wxyz)."""
    body_link: dict[str, int]
    """URDF link -> body id."""
    geom_finger: dict[int, str | None] = field(default_factory=dict)
    """Hand geom id -> finger whose joints move it (None: palm)."""
    tip_geom: dict[str, int] = field(default_factory=dict)
    """finger -> geom id of its fingertip contact sphere."""
    object_geoms: frozenset[int] = frozenset()
    """Geom ids of the object's convex pieces."""
    object_mass: float = 0.0
    """Object mass, kg."""
    p_object_com: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    """(3,) object centre of mass, object frame, m."""


def object_inertia(obj, mass: float | None, density: float) -> tuple[float, NDArray, NDArray]:
    """Mass (kg), centre of mass (3,) (object frame, m) and inertia (3, 3) about it (kg·m², object axes)
    of the object's watertight mesh ``obj.mesh`` at uniform density; ``mass`` None: volume × density."""
    mesh = obj.mesh
    volume = float(mesh.volume)
    if not volume > 0:
        raise ModelError(f"object {getattr(obj, 'name', '?')!r}: mesh volume {volume} is not positive")
    m = float(mass) if mass is not None else volume * density
    inertia_unit = np.asarray(mesh.moment_inertia, dtype=float) / float(mesh.density)  # per unit density
    return m, np.asarray(mesh.center_mass, dtype=float), inertia_unit * (m / volume)


def _quat_wxyz(R: NDArray) -> NDArray[np.float64]:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R, dtype=float).reshape(9))
    return quat


def _read_urdf(hand):
    """(child link -> its parent joint, link -> its child joints, link -> its collision elements) of
    ``hand.urdf_path`` (yourdfpy)."""
    import yourdfpy

    try:
        robot = yourdfpy.URDF.load(str(hand.urdf_path), build_scene_graph=False, load_meshes=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as exc:  # noqa: BLE001 - yourdfpy raises many kinds
        raise ModelError(f"{hand.urdf_path}: yourdfpy cannot read the URDF: {exc}") from exc
    parent_joint = {j.child: j for j in robot.robot.joints}
    children: dict[str, list] = {ln.name: [] for ln in robot.robot.links}
    for j in robot.robot.joints:
        children[j.parent].append(j)
    collisions = {ln.name: list(ln.collisions) for ln in robot.robot.links if ln.collisions}
    return parent_joint, children, collisions


def _add_joint(body, j, opts: SimOptions) -> None:
    """A hinge (revolute, continuous) or slide (prismatic) joint for URDF joint ``j``."""
    if j.type not in ("revolute", "continuous", "prismatic"):
        raise ModelError(f"joint {j.name!r}: type {j.type!r} is not supported by the MuJoCo model")
    hinge = j.type != "prismatic"
    axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=float)
    joint = body.add_joint(
        name=j.name,
        type=mujoco.mjtJoint.mjJNT_HINGE if hinge else mujoco.mjtJoint.mjJNT_SLIDE,
        axis=axis / np.linalg.norm(axis),
        damping=opts.joint_damping,
        armature=opts.armature,
    )
    if j.type != "continuous" and j.limit is not None:
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        joint.range = [float(j.limit.lower), float(j.limit.upper)]
    else:
        joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE


def _contact(opts: SimOptions) -> dict[str, Any]:
    """Contact parameters given to every geom (a pair mixes both geoms' values: they are equal)."""
    return {"condim": opts.condim, "friction": [opts.friction, opts.torsional_friction, 1e-4],
            "solref": list(opts.solref), "solimp": list(opts.solimp)}


def _add_hand(spec: mujoco.MjSpec, hand, opts: SimOptions) -> dict[str, Any]:
    """Bodies, joints and sphere geoms of the hand under the world body; returns link -> MjsBody."""
    parent_joint, children, collisions = _read_urdf(hand)
    use_urdf = opts.hand_collision == "urdf" or (opts.hand_collision == "auto" and bool(collisions))
    if opts.hand_collision == "urdf" and not collisions:
        raise ModelError(f"{hand.urdf_path}: SimOptions.hand_collision='urdf' but no link has a <collision>")
    palm = spec.worldbody.add_body(name=hand.root_link, quat=np.asarray(opts.palm_wxyz, dtype=float))
    bodies = {hand.root_link: palm}
    stack = [hand.root_link]
    while stack:
        link = stack.pop()
        for j in children.get(link, []):
            T = np.asarray(j.origin if j.origin is not None else np.eye(4), dtype=float)
            body = bodies[link].add_body(name=j.child, pos=T[:3, 3], quat=_quat_wxyz(T[:3, :3]))
            body.gravcomp = 1.0
            if j.type != "fixed":
                _add_joint(body, j, opts)
                if j.mimic is not None:  # q_child = multiplier * q_parent + offset
                    spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=j.name, name2=j.mimic.joint,
                                      data=[float(j.mimic.offset or 0.0), float(j.mimic.multiplier or 1.0),
                                            0, 0, 0, 0, 0, 0, 0, 0, 0])
            bodies[j.child] = body
            stack.append(j.child)
    for s in hand.spheres:
        if use_urdf and not s.is_tip:
            continue
        bodies[s.link].add_geom(
            name=("tip:" if s.is_tip else "sphere:") + (s.label or s.link),
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[float(s.radius), 0.0, 0.0],
            pos=np.asarray(s.center_link, dtype=float),
            density=opts.hand_density,
            contype=_HAND_GROUP,
            conaffinity=_OBJECT_GROUP | (_HAND_GROUP if opts.hand_self_collision else 0),
            rgba=[0.2, 0.4, 0.9, 1.0] if s.is_tip else [0.3, 0.3, 0.35, 0.5],
            **_contact(opts),
        )
    if use_urdf:
        _add_urdf_collisions(spec, hand, bodies, collisions, opts)
    for link, body in bodies.items():
        if link != hand.root_link and body.first_geom() is None:  # no geometry: a token mass (gravcomp)
            body.explicitinertial = True
            body.mass, body.inertia = _TOKEN_MASS, [_TOKEN_MASS * 1e-4] * 3
    _exclude_hand_pairs(spec, hand, parent_joint)
    return bodies


def _add_urdf_collisions(spec: mujoco.MjSpec, hand, bodies: dict, collisions: dict, opts: SimOptions) -> None:
    """Geoms ``"urdf:<link>#k"`` for the URDF's collision elements, except on the links with a tip sphere."""
    tip_links, base = {s.link for s in hand.spheres if s.is_tip}, Path(hand.urdf_path).parent
    for link, items in collisions.items():
        if link in bodies and link not in tip_links:
            for k, c in enumerate(items):
                _add_urdf_geom(spec, bodies[link], f"urdf:{link}#{k}", c, base, opts)


def _add_urdf_geom(spec: mujoco.MjSpec, body, name: str, c, base: Path, opts: SimOptions) -> None:
    """One geom for URDF collision element ``c`` (box, cylinder, sphere or mesh, at its origin)."""
    T = np.asarray(c.origin if c.origin is not None else np.eye(4), dtype=float)
    g = c.geometry
    kw: dict[str, Any] = {}
    if g.box is not None:
        kw = {"type": mujoco.mjtGeom.mjGEOM_BOX, "size": 0.5 * np.asarray(g.box.size, dtype=float)}
    elif g.cylinder is not None:
        kw = {"type": mujoco.mjtGeom.mjGEOM_CYLINDER, "size": [g.cylinder.radius, 0.5 * g.cylinder.length, 0]}
    elif g.sphere is not None:
        kw = {"type": mujoco.mjtGeom.mjGEOM_SPHERE, "size": [g.sphere.radius, 0, 0]}
    elif g.mesh is not None:
        import trimesh

        mesh = trimesh.load(base / g.mesh.filename, force="mesh")
        if g.mesh.scale is not None:
            mesh.apply_scale(np.broadcast_to(np.asarray(g.mesh.scale, dtype=float), 3))
        spec.add_mesh(name=name, uservert=np.asarray(mesh.vertices, dtype=float).reshape(-1).tolist())
        kw = {"type": mujoco.mjtGeom.mjGEOM_MESH, "meshname": name}
    else:  # pragma: no cover - yourdfpy reads only these four
        raise ModelError(f"{name}: unsupported URDF collision geometry {g}")
    affinity = _OBJECT_GROUP | (_HAND_GROUP if opts.hand_self_collision else 0)
    body.add_geom(name=name, pos=T[:3, 3], quat=_quat_wxyz(T[:3, :3]), density=opts.hand_density,
                  contype=_HAND_GROUP, conaffinity=affinity, rgba=[0.3, 0.3, 0.35, 0.5], **kw,
                  **_contact(opts))


def _exclude_hand_pairs(spec: mujoco.MjSpec, hand, parent_joint: dict) -> None:
    """Exclude contacts between bodies of the same finger and between adjacent links."""
    pairs: set[tuple[str, str]] = set()
    for child, j in parent_joint.items():
        pairs.add(tuple(sorted((j.parent, child))))
    finger_links: dict[str, set[str]] = {}
    for f in hand.fingers:
        link, chain = hand.tip_links[f], set()
        while link in parent_joint:
            chain.add(link)
            link = parent_joint[link].parent
        finger_links[f] = chain
    for chain in finger_links.values():
        ordered = sorted(chain)
        pairs.update((a, b) for i, a in enumerate(ordered) for b in ordered[i + 1:])
    for a, b in sorted(pairs):
        spec.add_exclude(bodyname1=a, bodyname2=b)


def _add_actuators(spec: mujoco.MjSpec, hand, opts: SimOptions) -> None:
    """One position actuator per actuated joint (gain kp, damping kv, torque limit); targets unbounded."""
    for name in hand.joint_names:
        act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=opts.kp, kv=opts.kv)
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-opts.force_limit, opts.force_limit]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE  # a target beyond a limit presses on it


def _add_object(spec: mujoco.MjSpec, obj, opts: SimOptions) -> tuple[float, NDArray]:
    """The object's free body with one convex mesh geom per piece; returns (mass kg, com (3,) m)."""
    mass, com, inertia = object_inertia(obj, opts.object_mass, opts.object_density)
    body = spec.worldbody.add_body(name=OBJECT_BODY)
    body.add_freejoint(name=OBJECT_BODY + "_free")
    body.explicitinertial = True
    body.mass = mass
    body.ipos = com
    body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2],
                        inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    for i, piece in enumerate(obj.pieces):
        verts = np.asarray(piece.vertices, dtype=float)
        mesh = spec.add_mesh(name=f"piece{i}", uservert=verts.reshape(-1).tolist())
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # geoms carry no mass (explicit)
        body.add_geom(
            name=f"piece{i}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"piece{i}",
            contype=_OBJECT_GROUP, conaffinity=_HAND_GROUP, mass=0.0, rgba=[0.95, 0.7, 0.2, 1.0],
            **_contact(opts),
        )
    return mass, com


def _set_physics(spec: mujoco.MjSpec, opts: SimOptions) -> None:
    spec.option.timestep = opts.timestep
    spec.option.integrator = _INTEGRATORS[opts.integrator]
    spec.option.cone = _CONES[opts.cone]
    spec.option.impratio = opts.impratio
    spec.option.iterations = opts.solver_iterations
    spec.option.gravity = opts.R_world_palm @ np.asarray(opts.gravity_palm, dtype=float)


def build_model(hand, obj, options: SimOptions | None = None) -> SimModel:
    """Compile the MuJoCo model of ``hand`` (fixed in the world) and ``obj`` (a free body).

    Args:
        hand: the project's Hand (uses urdf_path, root_link, joint_names, q_lower/q_upper, fingers,
            tip_links, spheres).
        obj: the project's ObjectModel (uses mesh, pieces[i].vertices).
        options: physical constants (default `SimOptions()`).

    Raises:
        ModelError: the URDF cannot be read or has an unsupported joint, or MuJoCo rejects the model.
    """
    opts = options or SimOptions()
    spec = mujoco.MjSpec()
    spec.modelname = f"{getattr(hand, 'name', 'hand')}_{getattr(obj, 'name', 'object')}"
    spec.compiler.degree = False
    _set_physics(spec, opts)
    _add_hand(spec, hand, opts)
    _add_actuators(spec, hand, opts)
    mass, com = _add_object(spec, obj, opts)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise ModelError(f"MuJoCo cannot compile the model of {spec.modelname}: {exc}") from exc
    return _index(model, spec, hand, mass, com)


def _index(model: mujoco.MjModel, spec: mujoco.MjSpec, hand, mass: float, com: NDArray) -> SimModel:
    jids = [model.joint(n).id for n in hand.joint_names]
    obj_body = model.body(OBJECT_BODY).id
    body_link = {model.body(i).name: i for i in range(model.nbody) if i not in (0, obj_body)}
    finger_of_link = {}
    for s in hand.spheres:
        finger_of_link.setdefault(s.link, s.finger)
    from regrasp_casadi.link_meshes import finger_links

    for link, finger in finger_links(hand).items():
        finger_of_link.setdefault(link, finger)
    geom_finger, tip_geom, object_geoms = {}, {}, set()
    for g in range(model.ngeom):
        name = model.geom(g).name
        if model.geom_bodyid[g] == obj_body:
            object_geoms.add(g)
            continue
        geom_finger[g] = finger_of_link.get(model.body(model.geom_bodyid[g]).name)
        if name.startswith("tip:"):
            tip_geom[geom_finger[g]] = g
    return SimModel(
        model=model, spec=spec,
        qpos_hand=np.array([model.jnt_qposadr[j] for j in jids], dtype=np.int64),
        dof_hand=np.array([model.jnt_dofadr[j] for j in jids], dtype=np.int64),
        actuator=np.array([model.actuator(n).id for n in hand.joint_names], dtype=np.int64),
        object_body=obj_body, qpos_object=int(model.jnt_qposadr[model.body_jntadr[obj_body]]),
        body_link=body_link, geom_finger=geom_finger, tip_geom=tip_geom,
        object_geoms=frozenset(object_geoms), object_mass=mass, p_object_com=np.asarray(com),
    )
