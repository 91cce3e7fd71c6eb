"""SLAM and exploration in the apartment scene: the robot maps the rooms by itself, and the
occupancy grid is saved as a PGM image (ROS map_server's format), with the 3-D map's size.

    python examples/python/slam.py --out map.pgm
"""

import argparse

import numpy as np

from ferrobot import Robot


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="map.pgm", help="the occupancy grid, as PGM")
    parser.add_argument("--seconds", type=float, default=60.0, help="how long to explore (simulated)")
    args = parser.parse_args()
    bot = Robot("locobot", scene="apartment", use_arm=False, slam=True)
    motion = bot.base.explore(wait=False)
    bot.wait(args.seconds)
    if not motion.done():
        motion.cancel()
    odom, vslam = bot.base.get_state("odom"), bot.base.get_state("vslam")
    print("odometry (%.2f, %.2f, %.2f), SLAM (%.2f, %.2f, %.2f)" % (*odom, *vslam))
    cells, resolution, origin = bot.slam_occupancy_map()
    pgm = np.where(cells == 0, 254, np.where(cells == 100, 0, 205)).astype(np.uint8)[::-1]
    with open(args.out, "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (pgm.shape[1], pgm.shape[0]))
        f.write(pgm.tobytes())
    pts, _ = bot.slam_map_3d(0.05)
    print("map %dx%d cells of %.2f m at (%.2f, %.2f) -> %s; 3-D map %d points" % (cells.shape[1], cells.shape[0], resolution, *origin, args.out, len(pts)))


if __name__ == "__main__":
    main()
