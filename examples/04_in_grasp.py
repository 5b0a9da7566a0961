"""One reposing (OPT2): move a held box 5 mm up and turn it 5° without letting go.

Solves the in-grasp manipulation NLP once with a desired object pose: all 16 joints move, the object
follows, and the relaxed-rigidity terms keep every fingertip where it is on the box. Look at how close
the object gets to the target and how little the contacts slip.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from regrasp_casadi import InGraspNLP, RegraspProblem
from regrasp_casadi.transforms import make_T, rot_axis_angle, rotation_angle

PROBLEM = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lift", type=float, default=0.005, help="translation along palm z, m")
    parser.add_argument("--turn", type=float, default=5.0, help="rotation about palm x, degrees")
    args = parser.parse_args(argv)

    problem = RegraspProblem.load(PROBLEM)
    hand, obj, grasp = problem.hand, problem.obj, problem.grasp0
    T0 = np.asarray(grasp.T_palm_object)
    R_turn = rot_axis_angle([1.0, 0.0, 0.0], np.radians(args.turn))
    T_target = make_T(R_turn @ T0[:3, :3], T0[:3, 3] + [0.0, 0.0, args.lift])

    nlp = InGraspNLP(hand, obj, "svd")
    result = nlp.solve(grasp.q, T0, grasp.tip_centers_object, T_target=T_target)

    dt = np.linalg.norm(result.T_palm_object[:3, 3] - T_target[:3, 3]) * 1e3
    da = np.degrees(rotation_angle(result.T_palm_object[:3, :3], T_target[:3, :3]))
    print(f"status {result.status}, {result.iterations} IPOPT iterations, {result.solve_time * 1e3:.1f} ms")
    print(f"object {dt:.2f} mm and {da:.2f}° from the target pose")
    print(f"largest contact slip {result.max_slip * 1e3:.4f} mm; hand at least "
          f"{result.min_clearance * 1e3:.2f} mm from the box except at the fingertips")


if __name__ == "__main__":
    main()
