"""Hand kinematics: symbolic forward kinematics of the Allegro hand.

Builds the shipped Allegro right hand from its URDF, evaluates the palm-frame pose of every link and the
fingertip contact-sphere centres at a joint configuration, and the tip Jacobian of the index finger —
all from CasADi SX functions built once. Look at how a fingertip moves when one joint moves: the
Jacobian column predicts it, a finite difference confirms it.
"""

from __future__ import annotations

import argparse

import numpy as np

from regrasp_casadi import Hand


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of the random joint configuration")
    args = parser.parse_args(argv)

    hand = Hand.allegro_right()
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(hand.q_lower, hand.q_upper)

    poses = hand.fk(q)  # link name -> (4, 4) T_palm_link
    tips = hand.tip_positions(q)  # (4, 3) tip-sphere centres, palm frame, m
    J = hand.tip_jacobian(q, "index")  # (3, 16), m/rad

    j = int(hand.finger_joints["index"][1])  # the index finger's first flexion joint
    h = 1e-6
    dq = np.zeros(hand.n_joints)
    dq[j] = h
    fd = (hand.tip_positions(q + dq)[0] - hand.tip_positions(q - dq)[0]) / (2 * h)

    print(f"{hand.name}: {hand.n_joints} joints, {len(poses)} links, {len(hand.spheres)} collision spheres")
    for finger, p in zip(hand.fingers, tips, strict=True):
        print(f"  {finger:6s} tip centre (palm frame) = {np.array2string(p * 1e3, precision=1)} mm")
    print(f"  d tip_index / d {hand.joint_names[j]}: Jacobian {np.array2string(J[:, j], precision=5)}"
          f", finite difference {np.array2string(fd, precision=5)} m/rad")


if __name__ == "__main__":
    main()
