"""The camera's point cloud in the robot's base frame: PyRobot's realtime_point_cloud.py
without its open3d window (the cloud goes to a PLY file instead; open in MeshLab or Blender).

    python examples/python/point_cloud.py --out cloud.ply
"""

import argparse

import numpy as np

from ferrobot import Robot


def filter_points(pts, colors, z_lowest=0.01):
    """PyRobot's filter: above the floor, within 0.5 m ahead and 0.4 m to either side."""
    valid = pts[:, 2] > z_lowest
    valid &= pts[:, 0] < 0.5
    valid &= np.abs(pts[:, 1]) < 0.4
    return pts[valid], colors[valid]


def write_ply(path, pts, colors):
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex %d\n" % len(pts))
        f.write("property float x\nproperty float y\nproperty float z\n")
        f.write("property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
        for p, c in zip(pts, colors):
            f.write("%.4f %.4f %.4f %d %d %d\n" % (*p, *c))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--floor_height", type=float, default=0.03, help="the floor's z, m")
    parser.add_argument("--scene", default="tabletop", help="the simulated scene")
    parser.add_argument("--out", default="cloud.ply", help="the PLY file to write")
    args = parser.parse_args()
    bot = Robot("locobot", scene=args.scene)
    bot.camera.set_pan_tilt(0, 0.7, wait=True)
    bot.arm.go_home()
    # PyRobot's example turned the arm aside with [1.96, 0.52, -0.51, 1.67, 0.01], beyond the
    # URDF's joint limits (1.57 rad; its driver clamped them). Ferrobot's arm refuses that:
    # clear_view() moves it out of the camera's view within its limits.
    bot.arm.clear_view()
    pts, colors = bot.camera.get_current_pcd(in_cam=False)
    pts, colors = filter_points(pts, colors, z_lowest=args.floor_height)
    write_ply(args.out, pts, colors)
    print("%d points above the floor in front of the robot (of the table and what is on it) -> %s" % (len(pts), args.out))


if __name__ == "__main__":
    main()
