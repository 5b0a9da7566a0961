"""The fingertips' smooth distance on the thin-walled shapes follows the exact one (issue 12, item 3).

OPT1 and OPT2 give each fingertip the smooth distance of the few planes near it (`ObjectModel.local_planes`
→ `signed_distance.local_signed_distance`) and correct it with an offset δ = exact − smooth taken at the
previous solution. Where that model's error changes by millimetres over a few millimetres of the surface
(the face-plane pieces of the walls, without edge planes, read a tip centre 14 mm off a rim or a piece
junction up to 5 mm short), the offsets of one solution do not fit the next and the finger gaits stall.
The tips' planes now come from the same hulls with every face and edge plane (`ObjectModel.local_pieces`);
checked here against trimesh's exact distance, independent of the pieces."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import trimesh

from regrasp_casadi import signed_distance
from regrasp_casadi.convex import LOCAL_PIECES, LOCAL_PLANES
from regrasp_casadi.hand import Hand
from regrasp_casadi.objects import WALL_TOLERANCE, ObjectModel
from regrasp_casadi.signed_distance import DEFAULT_TAU


def _tip_model_error(obj: ObjectModel, n: int = 400) -> np.ndarray:
    """|smooth local distance − exact distance| (m) at `n` tip-sphere centres one Allegro tip radius off
    the surface along its normal (those where the tip ball fits: its exact distance is the radius)."""
    rho = Hand.allegro_right().tip_radius
    pts, nrm = obj.mesh.sample(n, return_index=True, seed=7)  # trimesh's own generator: seeded here
    nrm = obj.mesh.face_normals[nrm]
    centres = pts + rho * nrm
    exact = -trimesh.proximity.signed_distance(obj.mesh, centres)  # trimesh: positive inside
    centres, exact = centres[np.abs(exact - rho) < 1e-4], exact[np.abs(exact - rho) < 1e-4]
    p = ca.SX.sym("p", 3)
    normals = ca.SX.sym("n", LOCAL_PIECES * LOCAL_PLANES * 3)
    offsets = ca.SX.sym("h", LOCAL_PIECES * LOCAL_PLANES)
    f = ca.Function("sd", [p, normals, offsets],
                    [signed_distance.local_signed_distance(normals, offsets, p, LOCAL_PIECES, DEFAULT_TAU)])
    smooth = []
    for c in centres:
        N, H = obj.local_planes(c[None])
        smooth.append(float(f(c, N.ravel(), H.ravel())))
    return np.abs(np.array(smooth) - exact)


@pytest.mark.parametrize("kind", ["cup", "mug"])
def test_tip_model_follows_the_exact_distance_on_cup_and_mug(kind):
    """Within 1 mm at 400 seeded surface samples (the face-plane pieces alone: p95 2.8 mm, max 5–10 mm).
    Measured over eight seeds: the largest 0.67–0.68 mm (cup), 0.68–0.84 mm (mug); an unseeded run found
    1.002 mm on the mug (trimesh's sampling does not read numpy's global seed)."""
    err = _tip_model_error(getattr(ObjectModel, kind)())
    assert len(err) > 300
    assert np.max(err) <= 1e-3


def test_tip_model_on_the_bowl_is_within_its_chords():
    """The bowl's pieces cut the inside of the sphere by chords (≤ 2 × the wall tolerance): the model is
    within that, and within 1 mm at the median (the face-plane pieces alone: median 1.4 mm)."""
    err = _tip_model_error(ObjectModel.bowl())
    assert np.max(err) <= 2 * WALL_TOLERANCE
    assert np.median(err) <= 1e-3


def test_only_the_walled_shapes_get_their_own_tip_pieces():
    """Other objects' tips select from `pieces` (their coacd / primitive pieces have edge planes already)."""
    box = ObjectModel.box()
    assert box.local_pieces is box.pieces
    cup = ObjectModel.cup()
    assert cup.local_pieces is not cup.pieces and len(cup.local_pieces) == len(cup.pieces)
