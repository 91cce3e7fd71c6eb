"""What the Python binding adds to a call, measured against the same call from Rust in the
same run (the extension times the Rust API in a loop: ferrobot._native.rust_call_seconds).

    python host/python/bench/overhead.py [--repeats 7]

Prints a markdown table: per call, the median over repeats of the mean time per call from
Rust and from Python, and the difference (the binding's overhead: argument and result
conversion, the GIL released and taken back, numpy arrays made). Build the package in release
(`pip install ./host/python`) for figures that mean anything.
"""

import argparse
import statistics
import time

import ferrobot
from ferrobot import Robot, _native

CALLS = {
    # call: (calls per repeat, the Python call)
    "get_joint_angles": (20000, lambda bot: bot.arm.get_joint_angles()),
    "pose_ee": (20000, lambda bot: bot.arm.pose_ee),
    "get_rgb_depth": (20, lambda bot: bot.camera.get_rgb_depth()),
}
GOALS_US = {"get_joint_angles": 10.0, "pose_ee": 10.0, "get_rgb_depth": 1000.0}


def python_seconds(bot, f, n):
    start = time.perf_counter()
    for _ in range(n):
        f(bot)
    return (time.perf_counter() - start) / n


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    bot = Robot("locobot", scene="tabletop")
    rows = []
    for name, (n, f) in CALLS.items():
        rust, py = [], []
        for _ in range(args.repeats):  # interleaved, so that drift hits both alike
            rust.append(_native.rust_call_seconds(bot, name, n))
            py.append(python_seconds(bot, f, n))
        r, p = statistics.median(rust) * 1e6, statistics.median(py) * 1e6
        rows.append((name, r, p, p - r, GOALS_US[name]))
    w, h = bot.configs.CAMERA.WIDTH, bot.configs.CAMERA.HEIGHT
    print(f"ferrobot {ferrobot.__version__}, locobot on the tabletop scene, images {w}x{h}, median of {args.repeats} repeats\n")
    print("| call | Rust, µs | Python, µs | overhead, µs | goal, µs |")
    print("|---|---:|---:|---:|---:|")
    for name, r, p, d, goal in rows:
        print(f"| `{name}` | {r:.2f} | {p:.2f} | {d:.2f} | {goal:.0f} |")


if __name__ == "__main__":
    main()
