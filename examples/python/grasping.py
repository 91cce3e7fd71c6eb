"""Grasping on the tabletop scene: Ferrobot's grasp skill looks at the table, segments the
objects, picks a top-down grasp, plans to it, grasps and lifts (PyRobot's grasping example
needed a PyTorch model; this one needs nothing but the robot).

    python examples/python/grasping.py --seed 3
"""

import argparse

import ferrobot
from ferrobot import Robot

STATES = {-1: "unknown", 0: "open", 1: "closing", 2: "holding an object", 3: "closed", 4: "opening"}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=3, help="the simulator's seed")
    args = parser.parse_args()
    bot = Robot("locobot", scene="tabletop", seed=args.seed)
    try:
        g = ferrobot.grasp(bot)
    except ferrobot.errors.Skill as e:  # no graspable object, or the grasp slipped
        print("no grasp:", e)
        raise SystemExit(1)
    x, y, z = g["position"]
    print("saw %d objects; grasped at (%.3f, %.3f, %.3f) m, yaw %.2f rad, %.3f m wide" % (g["objects"], x, y, z, g["yaw"], g["width"]))
    print("gripper after the lift:", STATES[g["gripper_state"]])


if __name__ == "__main__":
    main()
