"""One finger gait (OPT1): move the index fingertip 2 cm across a box while the others hold it.

Loads the shipped box problem, asks the index finger to move its contact 2 cm along the box face, and
solves the finger-gait NLP once. The step bound η = 1 cm stops it half way: look at the step length, the
exact distance of the tip sphere to the box (it stays on the surface) and the clearance of the finger's
other links.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from regrasp_casadi import FingerGaitNLP, RegraspProblem
from regrasp_casadi.transforms import inv_T, transform_points

PROBLEM = Path(__file__).resolve().parents[1] / "problems" / "box_rotate.yaml"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=0.02, help="how far to move the contact, m")
    args = parser.parse_args(argv)

    problem = RegraspProblem.load(PROBLEM)
    hand, obj, grasp = problem.hand, problem.obj, problem.grasp0
    r = hand.fingers.index("index")
    normal = obj.surface_normals(grasp.contacts_object[r][None])[0]
    across = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    along = np.cross(across, normal)  # in the face (the index finger of this problem has room there)
    along /= np.linalg.norm(along)
    goal_contact, _ = obj.closest_points((grasp.contacts_object[r] + args.distance * along)[None])
    goal_tip = goal_contact[0] + hand.tip_radius * normal  # goal tip-sphere centre, object frame

    nlp = FingerGaitNLP(hand, obj, "index")
    result = nlp.solve(grasp.q, grasp.T_palm_object, goal_tip)

    tip_before = grasp.tip_centers_object[r]
    T_object_palm = inv_T(grasp.T_palm_object)
    spheres = transform_points(T_object_palm, hand.sphere_centers(result.q, "index"))
    clearance = obj.exact_signed_distance(spheres) - hand.sphere_radii("index")
    print(f"status {result.status}, {result.iterations} IPOPT iterations, {result.solve_time * 1e3:.1f} ms")
    print(f"tip moved {np.linalg.norm(result.p_object_tip - tip_before) * 1e3:.2f} mm "
          f"(η = {nlp.options.eta * 1e3:.0f} mm), {np.linalg.norm(result.p_object_tip - goal_tip) * 1e3:.2f} "
          f"mm left to the goal")
    print(f"tip on the surface within {result.surface_error * 1e3:.4f} mm; other links at least "
          f"{clearance.min() * 1e3:.2f} mm from the box")


if __name__ == "__main__":
    main()
