"""Contact slip (the contact point on the object, not the fingertip centre) and pose error against closed
forms on a box."""

from __future__ import annotations

import numpy as np
import pytest

from regrasp_casadi.grasp_metrics import contact_slip, object_contacts, pose_error, slip_between
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.transforms import make_T, rot_axis_angle

A, B, C = 0.05, 0.07, 0.12  # box extents, m: faces at x = ±A/2, y = ±B/2, z = ±C/2
RHO = 0.012  # tip radius, m (slip depends on the tip centres only through their closest points)


@pytest.fixture(scope="module")
def box():
    return ObjectModel.box((A, B, C))


def test_a_tip_rolling_over_an_edge_slips_by_its_contact_not_its_centre(box):
    phi = np.radians(60.0)
    before = np.array([
        [A / 2 - 0.010, 0.0, C / 2 + RHO],  # on the top face, 10 mm from the edge x = A/2, z = C/2
        [0.0, 0.0, C / 2 + RHO],  # on the top face
        [0.0, B / 2 + RHO, 0.0],  # on the side face y = B/2
    ])
    after = np.array([
        [A / 2 + RHO * np.sin(phi), 0.005, C / 2 + RHO * np.cos(phi)],  # rolled 60° round the edge, 5 mm on
        [0.003, -0.004, C / 2 + RHO],  # slid 5 mm along the face
        [0.0, B / 2 + RHO, 0.0],  # still
    ])
    slip = contact_slip(box, before, after)
    # closed form: contact (A/2 − 10 mm, 0, C/2) → the edge point (A/2, 5 mm, C/2); 5 mm; 0
    assert slip == pytest.approx([np.hypot(0.010, 0.005), 0.005, 0.0], abs=1e-9)
    centre_motion = np.linalg.norm(after - before, axis=1)
    assert centre_motion[0] > slip[0] + 0.005  # the centre moved farther: that is not slip
    assert object_contacts(box, after)[0] == pytest.approx([A / 2, 0.005, C / 2], abs=1e-9)


def test_slip_between_contacts_and_its_shape_check():
    a = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    assert slip_between(a, a + [0.0, 0.003, 0.004]) == pytest.approx([0.005, 0.005])
    with pytest.raises(ValueError, match="different shapes"):
        slip_between(a, a[:1])


@pytest.mark.parametrize("angle", [0.0, 0.3, np.pi - 1e-9, np.pi])
def test_pose_error_is_origin_distance_and_geodesic_angle(angle):
    R = rot_axis_angle(np.array([1.0, 2.0, -2.0]) / 3.0, angle)
    T_a = make_T(rot_axis_angle([0.0, 0.0, 1.0], 0.7), [0.1, 0.0, 0.05])
    T_b = make_T(T_a[:3, :3] @ R, T_a[:3, 3] + [0.003, -0.004, 0.0])
    position, rotation = pose_error(T_a, T_b)
    assert position == pytest.approx(0.005, abs=1e-12)
    assert rotation == pytest.approx(angle, abs=1e-6)
