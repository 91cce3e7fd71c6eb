"""Pushing on the tabletop scene: Ferrobot's push skill looks at the table, segments the
objects (DBSCAN, as PyRobot's pushing example), chooses a push and makes it with the closed
gripper; the objects' positions before and after come from the camera.

    python examples/python/pushing.py --seed 1
"""

import argparse

import ferrobot
from ferrobot import Robot


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1, help="the simulator's seed")
    args = parser.parse_args()
    bot = Robot("locobot", scene="tabletop", seed=args.seed)
    p = ferrobot.push(bot)
    print("saw %d objects; pushed object %d from the %s side (lift %.3f m, roll %.2f rad)" % (p["objects"], p["target"], p["side"], p["lift"], p["roll"]))
    if any(p["base_move"]):
        print("the base moved (%.2f, %.2f) m to reach it" % tuple(p["base_move"]))


if __name__ == "__main__":
    main()
