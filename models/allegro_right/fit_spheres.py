"""Fit the conservative sphere cover of the Allegro right hand (v4) links to the vendor meshes.

Reads the vendor STL meshes from ``../shared/reference/allegro_right/meshes`` (reference data, not shipped),
fits a few spheres per rigid body and writes ``sphere_cover.json`` beside this file, which ``generate.py``
turns into ``<collision><sphere>`` elements of ``allegro_right.urdf``. Run from anywhere:

    python models/allegro_right/fit_spheres.py [--reference DIR]

Method (per rigid body, in its link frame, metres):
1. Points = every mesh vertex plus 20,000 area-uniform surface samples (seed 0).
2. Distal bodies (distal link + rubber tip) only, in the tip link frame: the tip's hemispherical cap IS the
   fingertip contact sphere (radius 14 mm at (0, 0, 0.002)); its vertices lie on it to within 1e-9 m, so
   points of the cap half-space (z >= 0.002) within ``TIP_TOL`` = 1e-6 m of it count as covered (nothing
   else is excused: every other point lies inside a cover sphere, margin >= 0). The tip's cylindrical part
   (radius 14 mm, z in [-0.012, 0.002]) is covered by ONE sphere centred on the tip axis behind the cap:
   centre z on a 0.1 mm grid in [-0.012, 0.002], radius = the farthest non-cap tip point rounded up to
   0.1 mm, z chosen to maximise the contact-cone half-angle (below). Both are fixed spheres; points inside
   a fixed sphere are dropped and the remaining k - 1 spheres cover the rest of the body (steps 3-5).
   Contact cone: a contact at outward unit direction u (from the tip centre c_t towards the object) keeps a
   sphere (c, rho) on the same rigid body >= BETA from the contact's tangent plane iff
   u.(c - c_t) <= r - rho - BETA. The half-angle ``cone_half_angle`` is the largest theta for which this
   holds for all u within theta of the tip axis (+z of the tip link); every non-tip sphere of a distal body
   must reach ``CONE_MIN`` = 60 deg, so that no fingertip contact inside that cone forces a non-tip contact.
3. k-means (scipy ``kmeans2``, 8 seeds) on the points scaled by per-axis weights (finger links cluster along
   their length, the palm in its plane), then per cluster an enclosing sphere (Badoiu-Clarkson centre,
   radius =
   farthest point + margin).
4. Greedy shrink: each sphere in turn is re-centred and shrunk to enclose only the points no other sphere
   covers (so coverage is kept at every step); repeated 3 times.
5. The seed with the smallest sum of r^3 among those whose spheres all reach ``CONE_MIN`` (distal bodies)
   wins. Coordinates are rounded outwards (radius up by the rounding
   error of the centre) to 0.1 mm and the enclosure is re-checked on all vertices.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import trimesh
from scipy.cluster.vq import kmeans2

HERE = Path(__file__).resolve().parent
MARGIN = 0.0002  # m, added to every radius (covers faces spanning two spheres)
TIP_CENTER = np.array([0.0, 0.0, 0.002])  # tip link frame
TIP_RADIUS = 0.014
TIP_TOL = 1e-6  # m, a point this close to the contact sphere counts as covered (the cap's own vertices)
BETA = 0.001  # m, clearance of non-tip spheres from the object (the planner's beta)
CONE_MIN = np.deg2rad(60.0)  # required contact-cone half-angle around the tip axis

# body name -> (meshes [(file, T_link_mesh)], number of cover spheres (distal bodies: incl. the tip-cylinder
# sphere), k-means axis weights, fingertip contact sphere (centre, radius) in the link frame or None);
# on distal bodies the rubber tip is the LAST mesh
FINGER_TIP_OFFSET = 0.0267
THUMB_TIP_OFFSET = 0.0423


def _T_z(z: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z
    return T


def _T_rx_pi() -> np.ndarray:
    T = np.eye(4)
    T[1, 1] = T[2, 2] = -1.0
    return T


BODIES = {
    "palm": ([("base_link.STL", np.eye(4))], 14, (0.15, 1.0, 1.0), None),
    "proximal_base": ([("link_0.0.STL", np.eye(4))], 2, (0.1, 0.1, 1.0), None),
    "proximal": ([("link_1.0.STL", np.eye(4))], 4, (0.1, 0.1, 1.0), None),
    "middle": ([("link_2.0.STL", np.eye(4))], 3, (0.1, 0.1, 1.0), None),
    "distal": (
        [("link_3.0.STL", np.eye(4)), ("link_3.0_tip.STL", _T_z(FINGER_TIP_OFFSET))],
        3,
        (0.1, 0.1, 1.0),
        (TIP_CENTER + [0, 0, FINGER_TIP_OFFSET], TIP_RADIUS),
    ),
    "thumb_base": ([("link_12.0_right.STL", _T_rx_pi())], 3, (1.0, 1.0, 1.0), None),
    "thumb_proximal": ([("link_13.0.STL", np.eye(4))], 2, (0.1, 0.1, 1.0), None),
    "thumb_middle": ([("link_14.0.STL", np.eye(4))], 4, (0.1, 0.1, 1.0), None),
    "thumb_distal": (
        [("link_15.0.STL", np.eye(4)), ("link_15.0_tip.STL", _T_z(THUMB_TIP_OFFSET))],
        4,
        (0.1, 0.1, 1.0),
        (TIP_CENTER + [0, 0, THUMB_TIP_OFFSET], TIP_RADIUS),
    ),
}


def enclosing_sphere(P: np.ndarray, iters: int = 400) -> tuple[np.ndarray, float]:
    """Approximate minimum enclosing sphere (Badoiu-Clarkson); the radius is exact for the returned centre."""
    c = P.mean(axis=0)
    for i in range(1, iters + 1):
        far = P[np.argmax(((P - c) ** 2).sum(1))]
        c = c + (far - c) / (i + 1)
    return c, float(np.sqrt(((P - c) ** 2).sum(1).max()))


def cone_half_angle(c: np.ndarray, rho: float, c_tip: np.ndarray, r: float = TIP_RADIUS,
                    beta: float = BETA) -> float:
    """Largest contact-cone half-angle (rad) around the tip axis +z that sphere (c, rho) allows.

    For d = c - c_tip at angle phi from +z and s = r - rho - beta, max over u within theta of +z of u.d is |d|
    if phi <= theta, else |d| cos(phi - theta); it is <= s iff theta <= phi - arccos(s / |d|). Returns pi
    when s >= |d| (any direction), a value <= 0 when no cone works. c, c_tip: (3,) in a frame whose z axis is
    the tip axis, m.
    """
    d = np.asarray(c, float) - np.asarray(c_tip, float)
    n = float(np.linalg.norm(d))
    s = r - rho - beta
    if s >= n:
        return float(np.pi)
    if n == 0.0:
        return -float(np.pi)
    phi = float(np.arccos(np.clip(d[2] / n, -1.0, 1.0)))
    return phi - float(np.arccos(max(s / n, -1.0)))


def fit_body(P: np.ndarray, k: int, w: np.ndarray, seeds: int = 8, c_tip: np.ndarray | None = None):
    """k spheres covering points P (n, 3); with ``c_tip``, only seeds whose spheres all reach CONE_MIN."""
    best = None
    for seed in range(seeds):
        _, lab = kmeans2(P * w, k, seed=seed, minit="++")
        if len(np.unique(lab)) < k:
            continue
        C, R = [], []
        for j in range(k):
            c, r = enclosing_sphere(P[lab == j])
            C.append(c)
            R.append(r + MARGIN)
        C, R = np.array(C), np.array(R)
        for _ in range(3):
            for j in range(k):
                D = np.sqrt(((P[:, None, :] - C[None]) ** 2).sum(-1))
                others = np.delete(np.arange(k), j)
                own = ~(D[:, others] <= R[others]).any(axis=1)
                if own.sum() == 0:
                    continue
                c, r = enclosing_sphere(P[own])
                C[j], R[j] = c, r + MARGIN
        # 0.1 mm of slack for the outward rounding in main()
        if c_tip is not None:
            cones = [cone_half_angle(c, r + 1e-4, c_tip) for c, r in zip(C, R, strict=True)]
            if min(cones) < CONE_MIN:
                continue
        score = float((R**3).sum())
        if best is None or score < best[0]:
            best = (score, C.copy(), R.copy())
    if best is None:
        raise RuntimeError(f"no seed gave {k} spheres reaching the {np.rad2deg(CONE_MIN):.0f} deg cone")
    return best[1], best[2]


def tip_cylinder_sphere(Q: np.ndarray, c_tip: np.ndarray, tip_offset: float) -> tuple[np.ndarray, float]:
    """The on-axis sphere covering points Q (n, 3; the tip's non-cap points incl. the cap's rim ring at the
    cylinder's top, link frame) with the widest cone.

    Centre (0, 0, z) with tip-frame z on a 0.1 mm grid in [-0.012, 0.002]; radius = farthest point, rounded
    up to 0.1 mm.
    """
    best = None
    for z_tip in np.arange(-120, 21) * 1e-4:
        c = np.array([0.0, 0.0, round(z_tip + tip_offset, 4)])
        rho = float(np.ceil(np.sqrt(((Q - c) ** 2).sum(1)).max() * 1e4 - 1e-9) / 1e4)
        key = (cone_half_angle(c, rho, c_tip), -rho)
        if best is None or key > best[0]:
            best = (key, c, rho)
    return best[1], best[2]


def body_points(ref: Path, meshes) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """Vertices, surface samples, total volume and, per vertex / sample, the index of its mesh."""
    verts, samples, vid, sid, vol = [], [], [], [], 0.0
    for i, (fname, T) in enumerate(meshes):
        m = trimesh.load(ref / "meshes" / fname)
        m.apply_transform(T)
        verts.append(np.asarray(m.vertices))
        samples.append(np.asarray(trimesh.sample.sample_surface(m, 20000, seed=0)[0]))
        vid.append(np.full(len(m.vertices), i))
        sid.append(np.full(len(samples[-1]), i))
        vol += m.volume
    return np.vstack(verts), np.vstack(samples), vol, np.concatenate(vid), np.concatenate(sid)


def union_volume(C, R, lo, hi, n=400_000, seed=0) -> float:
    rng = np.random.default_rng(seed)
    X = rng.uniform(lo, hi, size=(n, 3))
    inside = np.zeros(n, bool)
    for c, r in zip(C, R, strict=True):
        inside |= ((X - c) ** 2).sum(1) <= r * r
    return float(inside.mean() * np.prod(hi - lo))


def _on_cap(X: np.ndarray, fixed) -> np.ndarray:
    """(n,) bool: point on the contact sphere's cap (in the half-space z >= the sphere centre's z, within
    TIP_TOL of the sphere or inside it); such points count as covered by the contact sphere."""
    if fixed is None:
        return np.zeros(len(X), bool)
    return (X[:, 2] >= fixed[0][2] - 1e-9) & (np.sqrt(((X - fixed[0]) ** 2).sum(1)) - fixed[1] <= TIP_TOL)


def _outside(X: np.ndarray, C: np.ndarray, R: np.ndarray, fixed) -> tuple[np.ndarray, np.ndarray]:
    """Per point: distance outside the nearest cover sphere (m; <= 0 inside) and ``_on_cap``."""
    return (np.sqrt(((X[:, None] - C[None]) ** 2).sum(-1)) - R).min(axis=1), _on_cap(X, fixed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", type=Path, default=HERE.parents[2] / "shared/reference/allegro_right")
    args = ap.parse_args()
    out, report = {}, {}
    for name, (meshes, k, w, fixed) in BODIES.items():
        V, S, vol, vid, sid = body_points(args.reference, meshes)
        P, pid = np.vstack([V, S]), np.concatenate([vid, sid])
        fixedC, fixedR = np.zeros((0, 3)), np.zeros(0)
        if fixed is not None:
            keep = ~_on_cap(P, fixed)  # the cap's points; the rest of the tip (the cylinder) is Q below
            P, pid = P[keep], pid[keep]
            tip_offset = float(fixed[0][2] - TIP_CENTER[2])
            c_cyl, r_cyl = tip_cylinder_sphere(P[pid == len(meshes) - 1], fixed[0], tip_offset)
            fixedC, fixedR = c_cyl[None], np.array([r_cyl])
            P = P[np.sqrt(((P - c_cyl) ** 2).sum(1)) > r_cyl]
            C, R = fit_body(P, k - 1, np.asarray(w), c_tip=fixed[0])
        else:
            C, R = fit_body(P, k, np.asarray(w))
        # round outwards to 0.1 mm: centre error <= 0.05 mm per axis -> radius += 0.0866 mm, rounded up
        Cr = np.vstack([fixedC, np.round(C, 4)])
        Rr = np.concatenate([fixedR, np.ceil((R + np.linalg.norm(C - np.round(C, 4), axis=1)) * 1e4) / 1e4])
        dv, tv = _outside(V, Cr, Rr, fixed)
        ds, ts = _outside(S, Cr, Rr, fixed)
        d_out, d_out_s = float(dv[~tv].max()), float(ds[~ts].max())
        assert d_out <= 0.0 and d_out_s <= 0.0, (name, d_out, d_out_s)
        allC, allR = Cr, Rr
        if fixed is not None:
            allC, allR = np.vstack([Cr, fixed[0]]), np.append(Rr, fixed[1])
        lo = np.minimum(V.min(0), (allC - allR[:, None]).min(0))
        hi = np.maximum(V.max(0), (allC + allR[:, None]).max(0))
        uv = union_volume(allC, allR, lo, hi)
        out[name] = [
            {"center": [float(x) for x in c], "radius": float(r)} for c, r in zip(Cr, Rr, strict=True)
        ]
        report[name] = {
            "spheres": int(k),
            "max_outside_vertices_m": d_out,
            "max_outside_samples_m": d_out_s,
            "vertices_on_contact_sphere_only": int((tv & (dv > 0)).sum()),
            "mesh_volume_m3": vol,
            "union_volume_m3": uv,
            "volume_ratio": uv / vol,
            "max_radius_m": float(Rr.max()),
        }
        msg = ""
        if fixed is not None:
            cones = [cone_half_angle(c, r, fixed[0]) for c, r in zip(Cr, Rr, strict=True)]
            assert min(cones) >= CONE_MIN, (name, np.rad2deg(cones))
            report[name]["cone_half_angle_deg"] = float(np.rad2deg(min(cones)))
            report[name]["cone_half_angle_per_sphere_deg"] = [float(np.rad2deg(a)) for a in cones]
            n_cap = report[name]["vertices_on_contact_sphere_only"]
            msg = f" cone={np.rad2deg(min(cones)):.1f} deg ({n_cap} vertices on the contact sphere only)"
        print(
            f"{name:15s} k={k} max_out_vert={d_out * 1e3:+.3f} mm max_out_samples={d_out_s * 1e3:+.3f} mm "
            f"union/mesh volume={uv / vol:.2f} rmax={Rr.max() * 1e3:.1f} mm{msg}"
        )
    (HERE / "sphere_cover.json").write_text(json.dumps({"bodies": out, "check": report}, indent=1) + "\n")


if __name__ == "__main__":
    main()
