"""Recording from Python: a `with ferrobot.Recorder(...)` block around a program writes an MCAP
file that Foxglove's reader (not ours) reads, with the joint states the robot reported; bad
arguments are refused with the package's errors and touch no file."""

import os

import numpy as np
import pytest
from mcap.reader import make_reader

import ferrobot
from ferrobot import errors


@pytest.fixture(scope="module")
def bot():
    return ferrobot.Robot("locobot")


def test_a_recorded_program_reads_back_with_foxgloves_reader(bot, tmp_path):
    path = tmp_path / "run.mcap"
    target = [0.3, 0.2, -0.3, 0.4, 0.1]
    with ferrobot.Recorder(bot, path, camera=False) as rec:
        bot.arm.set_joint_positions(target)
        during = rec.stats()
    assert during["telemetry"] > 0
    assert rec.finish() is None  # finished by the block
    topics = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
            assert schema.encoding == "ros2msg"
    assert topics["/joint_states"] > 50
    assert "/camera/color/image_raw" not in topics
    assert topics["/ferrobot/commands"] > 0
    np.testing.assert_allclose(bot.arm.get_joint_angles(), target, atol=0.02)


def test_recorder_arguments_are_checked(bot, tmp_path):
    existing = tmp_path / "exists.mcap"
    existing.write_text("a user's file")
    with pytest.raises(errors.PathExists):
        ferrobot.Recorder(bot, existing)
    assert existing.read_text() == "a user's file"
    with pytest.raises(errors.Error):
        ferrobot.Recorder(bot, tmp_path / "no" / "such" / "dir.mcap")
    for bad in [None, 5, 1.5, ["a"], b"\x00", "\x00"]:
        with pytest.raises((TypeError, ValueError, errors.Error)):
            ferrobot.Recorder(bot, bad)
    for bad in [None, "locobot", 5]:
        with pytest.raises(TypeError):
            ferrobot.Recorder(bad, tmp_path / "x.mcap")
    assert sorted(os.listdir(tmp_path)) == ["exists.mcap"]


def test_recordings_export_to_a_lerobot_dataset_pyarrow_reads(bot, tmp_path):
    import json

    import pyarrow.parquet as pq

    paths = []
    for k, target in enumerate([[0.3, 0.2, -0.3, 0.4, 0.1], [0.0, 0.0, 0.0, 0.0, 0.0]]):
        paths.append(tmp_path / f"demo{k}.mcap")
        with ferrobot.Recorder(bot, paths[-1], camera=False):
            bot.arm.set_joint_positions(target)
    out = tmp_path / "dataset"
    s = ferrobot.export_lerobot(paths, out, ["reach", "home"], fps=10)
    assert (s["episodes"], s["tasks"], s["images"]) == (2, 2, False)
    info = json.loads((out / "meta" / "info.json").read_text())
    table = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert info["total_frames"] == table.num_rows == s["frames"]
    names = info["features"]["observation.state"]["names"]
    last = table.filter(table["episode_index"].to_numpy() == 0).to_pydict()["observation.state"][-1]
    # The first episode ends where the arm was sent, as the recording saw it.
    np.testing.assert_allclose(last[: 5], [0.3, 0.2, -0.3, 0.4, 0.1], atol=0.02)
    assert names[:5] == bot.arm.arm_joint_names
    with pytest.raises(errors.PathExists):
        ferrobot.export_lerobot(paths, out, "again")
    with pytest.raises(errors.Error):
        ferrobot.export_lerobot(paths, tmp_path / "d2", ["one"])
    assert not (tmp_path / "d2").exists()
