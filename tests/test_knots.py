"""`trajectory._knots`, the knot refinement every path is built on: a continuous curve is refined until no
point of the hand moves more than `max_point_step` between knots; a curve that jumps, or a knot the
curve cannot reach, fails the path, and the refinement stops there instead of bisecting on."""

from __future__ import annotations

import numpy as np
import pytest

from regrasp_casadi.hand import Hand
from regrasp_casadi.objects import ObjectModel
from regrasp_casadi.trajectory import _knots, motion_context


@pytest.fixture(scope="module")
def ctx():
    return motion_context(Hand.allegro_right(), ObjectModel.box((0.05, 0.05, 0.05)))


def _counting(curve):
    calls = []

    def counted(s, warm):
        calls.append(s)
        return curve(s, warm)

    return counted, calls


def _q_of(hand, s, jump=0.0):
    """Joints at s ∈ [0, 1]: an arc through the joint ranges (not straight in joint space), plus `jump`
    rad on every joint from s = 0.5 on."""
    lo, hi = hand.q_lower, hand.q_upper
    return lo + (hi - lo) * (0.3 + 0.3 * np.sin(np.pi * s) * np.linspace(0.2, 1.0, hand.n_joints)) + \
        (jump if s >= 0.5 else 0.0)


def test_a_continuous_curve_is_refined_until_every_point_moves_at_most_the_bound(ctx):
    s, Q, why = _knots(ctx, lambda s_, _w: (_q_of(ctx.hand, s_), ""), 3)
    assert why == ""
    assert np.max(ctx.segment_motion(Q)) <= ctx.options.max_point_step
    assert np.all(np.diff(s) > 0) and s[0] == 0.0 and s[-1] == 1.0


def test_a_jump_fails_the_path_after_a_few_rounds_that_do_not_shrink_it(ctx):
    s, Q, why = _knots(ctx, lambda s_, _w: (_q_of(ctx.hand, s_, jump=0.2), ""), 3)
    gaps = ctx.segment_motion(Q)
    assert "a jump" in why and np.max(gaps) > 10 * ctx.options.max_point_step
    # the jump's segment straddles s = 0.5, where the joints jump by 0.2 rad
    worst = int(np.argmax(gaps))
    assert s[worst] < 0.5 <= s[worst + 1]
    # the jump's segment was bisected only for the rounds that told it from a curve, not for all 12
    assert int(why.split(" after ")[1].split()[0]) < ctx.options.max_refinements


def test_a_knot_not_reached_fails_the_path_without_refining_it(ctx):
    def curve(s, _warm):
        return _q_of(ctx.hand, s), ("a tip is 2 mm from its target" if 0.4 < s < 0.6 else "")

    counted, calls = _counting(curve)
    s, Q, why = _knots(ctx, counted, 5)
    assert why.startswith("1 knot not reached, first at s = 0.500")
    assert len(calls) == 5 and len(s) == 5  # the coarse knots only
