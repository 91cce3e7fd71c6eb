"""Reads a Ferrobot recording with readers that are not Ferrobot's and checks every topic
against what the robot delivered (written by host/record/tests/integration/recording.rs).

Two readers: Foxglove's `mcap` (records, schemas, channels, the summary's statistics) and
rosbags (its own MCAP storage; its CDR decoder, with the message types parsed from each
file's ros2msg schemas). Exits 1 naming the first value that differs.

usage: check_recording.py FILE.mcap DIR   (DIR holds expected.json and the raw frames)
"""

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

F32 = 1e-6  # f32 values carried as float64: equal to the float32's value exactly; slack for sums


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def close(a, b, tol, what):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape or not np.allclose(a, b, atol=tol, rtol=0):
        fail(f"{what}: {a.tolist()} != {b.tolist()} (tolerance {tol})")


def quat_mul(a, b):
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return np.array([
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
    ])


def rotate(q, v):
    p = quat_mul(quat_mul(q, [v[0], v[1], v[2], 0.0]), [-q[0], -q[1], -q[2], q[3]])
    return p[:3]


def compose(a, b):
    """a then b: pose b (in a's child frame) carried into a's parent frame."""
    ta, qa = a
    tb, qb = b
    return (ta + rotate(qa, tb), quat_mul(qa, qb))


def chain(edges, src, dst):
    """Pose of frame src in frame dst, walking the child -> parent edges of /tf and /tf_static."""
    pose = (np.zeros(3), np.array([0, 0, 0, 1.0]))
    frame = src
    while frame != dst:
        if frame not in edges:
            fail(f"/tf has no path from {src} to {dst} (stuck at {frame})")
        parent, t, q = edges[frame]
        pose = compose((np.array(t), np.array(q)), pose)
        frame = parent
    return pose


def tf_edges(msg, edges):
    for tr in msg.transforms:
        t, r = tr.transform.translation, tr.transform.rotation
        edges[tr.child_frame_id] = (tr.header.frame_id, [t.x, t.y, t.z], [r.x, r.y, r.z, r.w])


def read_mcap(path):
    """Foxglove's reader: per-topic counts, encodings, and the summary's statistics."""
    counts = Counter()
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            if schema.encoding != "ros2msg" or channel.message_encoding != "cdr":
                fail(f"{channel.topic}: encodings {schema.encoding}/{channel.message_encoding}")
            counts[channel.topic] += 1
    if summary is None or summary.statistics.message_count != sum(counts.values()):
        fail("the summary's message count differs from the messages read")
    return counts


def main():
    path, work = Path(sys.argv[1]), Path(sys.argv[2])
    exp = json.loads((work / "expected.json").read_text())
    counts = read_mcap(path)
    if sum(counts.values()) != exp["messages"]:
        fail(f"{sum(counts.values())} messages, the recorder wrote {exp['messages']}")
    by_topic = {}
    with AnyReader([path]) as reader:
        for conn, t_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            by_topic.setdefault(conn.topic, []).append((t_ns, conn.msgtype, msg))
    for topic, n in counts.items():
        if len(by_topic.get(topic, [])) != n:
            fail(f"{topic}: rosbags read {len(by_topic.get(topic, []))}, mcap {n}")
    check_joints(exp, by_topic)
    check_tf(exp, by_topic)
    check_camera(exp, by_topic, work)
    check_events(exp, by_topic)
    urdf = by_topic["/robot_description"][0][2].data
    if "<robot" not in urdf or exp["ee_frame"] not in urdf:
        fail("/robot_description is not the robot's URDF")
    print("topics:", dict(sorted(counts.items())))
    print("OK: every topic decodes to the values recorded")


def check_joints(exp, by_topic):
    js = {t: m for t, _, m in by_topic["/joint_states"]}
    odom = {t: m for t, _, m in by_topic["/odom"]}
    for e in exp["telemetry"]:
        m = js.get(e["t_ns"])
        if m is None:
            fail(f"/joint_states has no message at {e['t_ns']} ns")
        if list(m.name) != exp["joints"] or m.header.stamp.sec * 10**9 + m.header.stamp.nanosec != e["t_ns"]:
            fail(f"/joint_states at {e['t_ns']}: names {list(m.name)} or stamp differ")
        # float32 values widened to float64: exactly equal.
        close(m.position, e["position"], 0, "/joint_states position")
        close(m.velocity, e["velocity"], 0, "/joint_states velocity")
        close(m.effort, e["effort"], 0, "/joint_states effort")
        o = odom[e["t_ns"]]
        p, q = o.pose.pose.position, o.pose.pose.orientation
        yaw = 2 * np.arctan2(q.z, q.w)
        yaw = (yaw + np.pi) % (2 * np.pi) - np.pi
        close([p.x, p.y, o.twist.twist.linear.x, o.twist.twist.angular.z],
              [e["odom"][0], e["odom"][1], e["odom"][3], e["odom"][4]], 0, "/odom")
        close([np.cos(yaw), np.sin(yaw)], [np.cos(e["odom"][2]), np.sin(e["odom"][2])], 1e-9, "/odom yaw")
    grip = [(t, m.data) for t, _, m in by_topic["/gripper/state"]]
    seen = [e["gripper"] for e in exp["telemetry"]]
    changes = [s for i, s in enumerate(seen) if i == 0 or s != seen[i - 1]]
    if [d for _, d in grip][-len(changes):] != changes[-len(changes):] or len(set(seen)) < 2:
        fail(f"/gripper/state {grip} against the states seen {changes}")


def check_tf(exp, by_topic):
    static = {}
    tf_edges(by_topic["/tf_static"][0][2], static)
    tf = {t: m for t, _, m in by_topic["/tf"]}
    for e in exp["telemetry"][:: max(1, len(exp["telemetry"]) // 25)]:
        edges = dict(static)
        tf_edges(tf[e["t_ns"]], edges)
        t, q = chain(edges, exp["ee_frame"], "base_link")
        want = e["ee_in_base"]
        close(t, want[:3], 1e-9, f"{exp['ee_frame']} in base_link through /tf")
        if abs(abs(float(np.dot(q, want[3:]))) - 1) > 1e-9:
            fail(f"{exp['ee_frame']} orientation through /tf: {q} != {want[3:]}")


def check_camera(exp, by_topic, work):
    color = {t: m for t, _, m in by_topic["/camera/color/image_raw"]}
    depth = {t: m for t, _, m in by_topic["/camera/aligned_depth_to_color/image_raw"]}
    info = {t: m for t, _, m in by_topic["/camera/color/camera_info"]}
    pose = {t: m for t, _, m in by_topic["/camera/pose"]}
    if len(color) != len(exp["frames"]):
        fail(f"{len(color)} colour images, the robot delivered {len(exp['frames'])} frames")
    for i, f in enumerate(exp["frames"]):
        c, d, k = color[f["t_ns"]], depth[f["t_ns"]], info[f["t_ns"]]
        if c.encoding != "rgb8" or d.encoding != "32FC1" or c.header.frame_id != exp["optical"]:
            fail(f"frame {i}: encodings {c.encoding}, {d.encoding} or frame {c.header.frame_id}")
        if [c.width, c.height] != f["size"] or c.step != 3 * c.width:
            fail(f"frame {i}: size {c.width}x{c.height}")
        if int(np.asarray(c.data, np.uint64).sum()) != f["rgb_sum"]:
            fail(f"frame {i}: colour differs")
        dm = np.frombuffer(bytes(d.data), "<f4").reshape(d.height, d.width)
        if int((dm > 0).sum()) != f["depth_valid"]:
            fail(f"frame {i}: valid depth pixels differ")
        if f["whole"]:
            if bytes(c.data) != (work / f"rgb-{i}.bin").read_bytes():
                fail(f"frame {i}: colour bytes differ")
            if bytes(d.data) != (work / f"depth-{i}.bin").read_bytes():
                fail(f"frame {i}: depth bytes differ")
        kk = np.asarray(k.k).reshape(3, 3)
        close([kk[0, 0], kk[1, 1], kk[0, 2], kk[1, 2]], f["k"], 0, f"frame {i} camera_info K")
        p = pose[f["t_ns"]].pose.position
        close([p.x, p.y, p.z], f["camera_in_base"], 0, f"frame {i} /camera/pose")


def check_events(exp, by_topic):
    log = [m.msg for _, _, m in by_topic.get("/rosout", [])]
    kinds = Counter(e["topic"] for e in exp["events"])
    for topic, n in kinds.items():
        if topic == "/rosout":
            continue
        got = by_topic.get(topic, [])
        if len(got) != n:
            fail(f"{topic}: {len(got)} messages, {n} events")
    for e in exp["events"]:
        t = e["t_ns"]
        if e["topic"] == "/cmd_vel":
            m = next(m for tt, _, m in by_topic["/cmd_vel"] if tt == t)
            close([m.linear.x, m.angular.z], e["values"], 0, "/cmd_vel")
        elif e["topic"] == "/joint_commands":
            ms = [m for tt, _, m in by_topic["/joint_commands"] if tt == t]
            if not any(np.allclose(m.points[0].positions, e["values"], atol=0) for m in ms):
                fail(f"/joint_commands at {t}: no knot at {e['values']}")
        elif e["topic"] == "/gripper/command":
            if not any(m.data == e["values"] for tt, _, m in by_topic["/gripper/command"] if tt == t):
                fail(f"/gripper/command at {t}: not {e['values']}")
        elif e["topic"] == "/slam/pose":
            m = next(m for tt, _, m in by_topic["/slam/pose"] if tt == t)
            p = m.pose.position
            close([p.x, p.y, p.z], e["values"], 0, "/slam/pose")
        elif e["topic"] == "/rosout" and e["values"] not in log:
            fail(f"/rosout lacks '{e['values']}'")
    if kinds["/slam/pose"] == 0 or kinds["/cmd_vel"] == 0 or kinds["/joint_commands"] == 0:
        fail(f"the robot's work made too few events to check: {dict(kinds)}")


if __name__ == "__main__":
    main()
