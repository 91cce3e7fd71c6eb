"""Reads a LeRobot dataset exported by Ferrobot with the libraries LeRobot reads it with
(pyarrow for the data and episodes, pandas for the tasks, PIL for the frames), rebuilds every
row from the recordings with readers that are not Ferrobot's (rosbags' MCAP storage and CDR
decoder), and checks the two agree. Exits 1 naming the first value that differs.

The rules it checks the export against (host/record/src/lerobot/episode.rs):
  - frame k of an episode is at t0 + round(k * 1e9 / fps) ns, t0 the first colour frame's
    log time; timestamp = k / fps;
  - observation.state: the joint positions of the last /joint_states at or before it, then
    /odom's x, y, yaw; action: the joint positions one frame later (the last frame's own),
    then the last /cmd_vel's linear.x and angular.z at or before it (0 before any);
  - the image: the colour frame nearest the instant, pixel for pixel;
  - stats: min, max, mean, std (population), count and numpy's quantiles.

usage: check_lerobot_export.py DATASET FPS TASK1,TASK2,... REC1.mcap [REC2.mcap ...]
"""

import io
import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from PIL import Image
from rosbags.highlevel import AnyReader

IMAGE = "observation.images.camera"


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def same(a, b, what, tol=0.0):
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.shape != b.shape or not np.allclose(a, b, atol=tol, rtol=0):
        fail(f"{what}: {a.tolist()[:8]} != {b.tolist()[:8]} (tolerance {tol})")


def yaw(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def read_recording(path):
    """Each stream of the recording: lists of (log time ns, value)."""
    s = {"states": [], "odom": [], "cmd": [], "frames": []}
    with AnyReader([Path(path)]) as reader:
        for conn, t, raw in reader.messages():
            if conn.topic not in ("/joint_states", "/odom", "/cmd_vel", "/camera/color/image_raw"):
                continue
            m = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/joint_states":
                s["states"].append((t, np.array(m.position, np.float32)))
            elif conn.topic == "/odom":
                p = m.pose.pose
                s["odom"].append((t, np.array([p.position.x, p.position.y, yaw(p.orientation)], np.float32)))
            elif conn.topic == "/cmd_vel":
                s["cmd"].append((t, np.array([m.linear.x, m.angular.z], np.float32)))
            else:
                if m.encoding != "rgb8":
                    fail(f"colour frame in {m.encoding}")
                s["frames"].append((t, np.frombuffer(m.data, np.uint8).reshape(m.height, m.width, 3)))
    for v in s.values():
        v.sort(key=lambda e: e[0])
    return s


def at_or_before(series, t, default=None):
    times = [e[0] for e in series]
    i = np.searchsorted(times, t, side="right") - 1
    if i < 0:
        return series[0][1] if default is None else default
    return series[i][1]


def nearest(series, t):
    times = np.array([e[0] for e in series], np.int64)
    after = int(np.searchsorted(times, t, side="left"))
    if after == 0:
        return series[0][1]
    if after < len(times) and times[after] - t < t - times[after - 1]:
        return series[after][1]
    return series[after - 1][1]


def expected_rows(rec, fps):
    """The rows of one episode, rebuilt from the recording."""
    frames = rec["frames"]
    t0, last = frames[0][0], frames[-1][0]
    period = 1e9 / fps
    n = int(math.floor((last - t0) / period + 1e-3)) + 1
    grid = [t0 + int(round(k * period)) for k in range(n)]
    rows = []
    for k, t in enumerate(grid):
        nxt = grid[min(k + 1, n - 1)]
        state = [at_or_before(rec["states"], t)]
        action = [at_or_before(rec["states"], nxt)]
        if rec["odom"]:
            state.append(at_or_before(rec["odom"], t))
            action.append(at_or_before(rec["cmd"], t, np.zeros(2, np.float32)) if rec["cmd"] else np.zeros(2, np.float32))
        rows.append((np.concatenate(state), np.concatenate(action), nearest(frames, t)))
    return rows


def check_stats(name, got, values, count):
    """A vector feature's statistics, each entry over the rows, against numpy's."""
    values = np.asarray(values, np.float64)
    want = {
        "min": values.min(axis=0), "max": values.max(axis=0),
        "mean": values.mean(axis=0), "std": values.std(axis=0),
    }
    for q, key in ((0.01, "q01"), (0.10, "q10"), (0.50, "q50"), (0.90, "q90"), (0.99, "q99")):
        want[key] = np.quantile(values, q, axis=0)
    for key, v in want.items():
        same(np.asarray(got[key]).reshape(-1), np.asarray(v).reshape(-1), f"stats {name}/{key}", 1e-9)
    if list(got["count"]) != [count]:
        fail(f"stats {name}/count {got['count']} != {count}")


def main():
    root, fps = Path(sys.argv[1]), int(sys.argv[2])
    tasks, recs = sys.argv[3].split(","), sys.argv[4:]
    info = json.loads((root / "meta/info.json").read_text())
    if info["codebase_version"] != "v3.0" or info["fps"] != fps:
        fail(f"info: {info['codebase_version']} at {info['fps']} fps")
    table = pq.read_table(root / "data/chunk-000/file-000.parquet")
    if set(table.column_names) != set(info["features"]):
        fail(f"data columns {table.column_names} != features {list(info['features'])}")
    task_table = pd.read_parquet(root / "meta/tasks.parquet")
    if list(task_table.index) != list(dict.fromkeys(tasks)) or list(task_table["task_index"]) != list(range(len(task_table))):
        fail(f"tasks: {task_table}")
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    if len(episodes) != len(recs) or info["total_episodes"] != len(recs):
        fail(f"{len(episodes)} episodes for {len(recs)} recordings")
    data = table.to_pydict()
    states, images, start = [], [], 0
    for e, (path, task) in enumerate(zip(recs, tasks)):
        rows = expected_rows(read_recording(path), fps)
        ep = episodes[e]
        n = len(rows)
        if (ep["episode_index"], ep["length"], ep["dataset_from_index"], ep["dataset_to_index"], ep["tasks"]) != (e, n, start, start + n, [task]):
            fail(f"episode {e}: {ep['episode_index'], ep['length'], ep['dataset_from_index'], ep['dataset_to_index'], ep['tasks']}; expected {n} rows from {start}")
        for k, (state, action, frame) in enumerate(rows):
            i = start + k
            if (data["episode_index"][i], data["frame_index"][i], data["index"][i]) != (e, k, i):
                fail(f"row {i}: indices {data['episode_index'][i], data['frame_index'][i], data['index'][i]}")
            if data["task_index"][i] != int(task_table.loc[task, "task_index"]):
                fail(f"row {i}: task index {data['task_index'][i]}")
            same(data["timestamp"][i], np.float32(k / fps), f"row {i} timestamp")
            same(data["observation.state"][i], state, f"row {i} observation.state")
            same(data["action"][i], action, f"row {i} action")
            img = np.asarray(Image.open(io.BytesIO(data[IMAGE][i]["bytes"])).convert("RGB"))
            if img.shape != frame.shape or not np.array_equal(img, frame):
                fail(f"row {i}: the image differs from the recording's nearest frame")
            states.append(data["observation.state"][i])
            images.append(img)
        same(ep["stats/observation.state/mean"], np.mean(data["observation.state"][start:start + n], axis=0), f"episode {e} state mean", 1e-9)
        start += n
    if start != table.num_rows or info["total_frames"] != start:
        fail(f"{table.num_rows} rows, info says {info['total_frames']}, recordings give {start}")
    stats = json.loads((root / "meta/stats.json").read_text())
    check_stats("observation.state", stats["observation.state"], states, start)
    check_stats("action", stats["action"], data["action"], start)
    # Images: per channel over every pixel of every row, scaled to [0, 1], shaped (3, 1, 1);
    # from numpy's counts of each channel's values.
    got = {k: np.asarray(v, np.float64) for k, v in stats[IMAGE].items()}
    if got["mean"].shape != (3, 1, 1) or list(stats[IMAGE]["count"]) != [start]:
        fail(f"image stats of shape {got['mean'].shape}, count {stats[IMAGE]['count']}")
    pixels = np.stack(images)
    for c in range(3):
        counts = np.bincount(pixels[..., c].reshape(-1), minlength=256).astype(np.float64)
        v = np.arange(256) / 255.0
        mean = (counts * v).sum() / counts.sum()
        std = math.sqrt((counts * (v - mean) ** 2).sum() / counts.sum())
        nz = np.nonzero(counts)[0]
        for key, want in (("min", nz[0] / 255.0), ("max", nz[-1] / 255.0), ("mean", mean), ("std", std)):
            same(got[key][c, 0, 0], want, f"stats {IMAGE}/{key} channel {c}", 1e-9)
    print(f"OK: {len(recs)} episodes, {start} rows, {len(task_table)} tasks at {fps} fps: every "
          f"state, action, frame and statistic as rebuilt from the recordings")


if __name__ == "__main__":
    main()
