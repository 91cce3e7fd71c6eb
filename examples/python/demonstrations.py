"""Demonstrations to a LeRobot dataset: each demonstration of a task recorded (MCAP with ROS 2
schemas), then all of them exported as one LeRobot dataset that LeRobot's own
`LeRobotDataset` trains from. Here the demonstrations are scripted reaches on the simulated
LoCoBot; on a robot, demonstrate by keys or gamepad (`ferrobot teleop ROBOT --record FILE`) or
by hand in teach mode, and export the files the same way.

    python examples/python/demonstrations.py --out-dir reach
"""

import argparse
import json
import os

import ferrobot

REACHES = [
    [0.4, 0.3, -0.2, 0.5, 0.0],
    [-0.4, 0.3, -0.2, 0.5, 0.0],
    [0.0, 0.5, -0.6, 0.9, 0.3],
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", default="reach", help="where the recordings and the dataset go")
    args = ap.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    bot = ferrobot.Robot("locobot")
    recordings = []
    for k, target in enumerate(REACHES):
        path = os.path.join(args.out_dir, f"reach-{k}.mcap")
        with ferrobot.Recorder(bot, path) as rec:
            bot.arm.set_joint_positions(target)
            bot.gripper.close()
            bot.gripper.open()
            bot.arm.go_home()
        print(f"{path}: {rec.finish() or 'recorded'}")
        recordings.append(path)
    dataset = os.path.join(args.out_dir, "dataset")
    s = ferrobot.export_lerobot(recordings, dataset, "reach out and come back", robot_type="locobot")
    with open(os.path.join(dataset, "meta", "info.json")) as f:
        info = json.load(f)
    shapes = {k: v["shape"] for k, v in info["features"].items() if not k.endswith("index")}
    print(f"{dataset}: {s['episodes']} episodes, {s['frames']} frames at {info['fps']} fps; {shapes}")


if __name__ == "__main__":
    main()
