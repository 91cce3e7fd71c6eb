"""Loads a LeRobot dataset exported by Ferrobot with LeRobot's own loader (`LeRobotDataset`,
the class its training scripts use) and checks what it gives: the episode count, fps and
frames of the metadata, the shapes and dtypes of every feature, each episode's task string,
every row's state and action against the data file as pyarrow reads it, images as LeRobot
decodes them against the PNGs, windows of future actions by `delta_timestamps` (which LeRobot
only serves when the timestamps are in step with fps) and a batch from a torch DataLoader.
Exits 1 naming the first thing that differs. Run by scripts/lerobot-check.sh.

usage: check_lerobot.py DATASET FPS TASK1,TASK2,...
"""

import io
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import torch
from PIL import Image
from lerobot.datasets.lerobot_dataset import LeRobotDataset

IMAGE = "observation.images.camera"


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def main():
    root, fps, tasks = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3].split(",")
    table = pq.read_table(root / "data/chunk-000/file-000.parquet").to_pydict()
    rows = len(table["index"])
    ds = LeRobotDataset("ferrobot/export-check", root=root)
    if (ds.num_episodes, ds.fps, ds.num_frames, len(ds)) != (len(tasks), fps, rows, rows):
        fail(f"episodes {ds.num_episodes}, fps {ds.fps}, frames {ds.num_frames}, len {len(ds)}; "
             f"expected {len(tasks)}, {fps}, {rows}")
    state_dim = len(table["observation.state"][0])
    action_dim = len(table["action"][0])
    h, w = np.asarray(Image.open(io.BytesIO(table[IMAGE][0]["bytes"]))).shape[:2]
    for i in range(rows):
        item = ds[i]
        e = table["episode_index"][i]
        if item["task"] != tasks[e] or int(item["episode_index"]) != e or int(item["index"]) != i:
            fail(f"row {i}: task {item['task']!r}, episode {item['episode_index']}, index {item['index']}")
        for key, dim in (("observation.state", state_dim), ("action", action_dim)):
            t = item[key]
            if t.dtype != torch.float32 or tuple(t.shape) != (dim,):
                fail(f"row {i} {key}: {t.dtype} {tuple(t.shape)}")
            if not np.array_equal(t.numpy(), np.asarray(table[key][i], np.float32)):
                fail(f"row {i} {key}: {t.numpy()} != {table[key][i]}")
        img = item[IMAGE]
        if tuple(img.shape) != (3, h, w) or img.dtype != torch.float32:
            fail(f"row {i} image: {img.dtype} {tuple(img.shape)}")
        png = np.asarray(Image.open(io.BytesIO(table[IMAGE][i]["bytes"])).convert("RGB"))
        if not np.array_equal((img.permute(1, 2, 0).numpy() * 255).round().astype(np.uint8), png):
            fail(f"row {i}: the image LeRobot decodes differs from the PNG")
    # Three future actions a frame apart, as a policy with an action chunk asks.
    window = LeRobotDataset("ferrobot/export-check", root=root,
                            delta_timestamps={"action": [0.0, 1.0 / fps, 2.0 / fps]})
    a = window[0]["action"]
    if tuple(a.shape) != (3, action_dim) or not np.array_equal(a[1].numpy(), np.asarray(table["action"][1], np.float32)):
        fail(f"action window: {tuple(a.shape)}")
    batch = next(iter(torch.utils.data.DataLoader(ds, batch_size=4, shuffle=False)))
    if tuple(batch[IMAGE].shape) != (4, 3, h, w) or tuple(batch["observation.state"].shape) != (4, state_dim):
        fail(f"batch: {tuple(batch[IMAGE].shape)}, {tuple(batch['observation.state'].shape)}")
    print(f"OK: LeRobot {__import__('lerobot').__version__} loads {ds.num_episodes} episodes, "
          f"{len(ds)} frames at {ds.fps} fps: state ({state_dim},), action ({action_dim},), "
          f"image (3, {h}, {w}), tasks {tasks}; every row equal to the data file; action windows "
          f"of 3 and batches of 4")


if __name__ == "__main__":
    main()
