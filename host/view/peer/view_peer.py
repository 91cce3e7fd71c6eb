"""A viewer of a Ferrobot live view, written from Foxglove's WebSocket protocol spec
(foxglove/ws-protocol, docs/spec.md) and sharing no code with Ferrobot: `websockets` for the
connection, rosbags' Jazzy type store to decode each message by its channel's schema name.

It connects with the subprotocol foxglove.websocket.v1, reads the server's info and its
channels, subscribes to some, reads for a while, unsubscribes from one, and prints one JSON
object: the channels, and per topic what it received and decoded.

usage: view_peer.py URL SECONDS
"""

import asyncio
import json
import struct
import sys
import time

import websockets
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)
WANTED = ["/joint_states", "/robot_description", "/tf_static", "/tf", "/camera/color/image_raw",
          "/arm/planned_path", "/scene/markers"]


def xyz(p):
    return [p.x, p.y, p.z]


async def main(url, seconds):
    out = {"received": {}, "errors": []}
    async with websockets.connect(url, subprotocols=["foxglove.websocket.v1"], max_size=None) as ws:
        out["subprotocol"] = ws.subprotocol
        info = json.loads(await ws.recv())
        out["server"] = {"op": info["op"], "name": info.get("name")}
        channels = {}
        subs = {}
        end = time.time() + seconds
        unsubscribed = False
        while time.time() < end:
            try:
                m = await asyncio.wait_for(ws.recv(), timeout=0.5)
            except asyncio.TimeoutError:
                continue
            if isinstance(m, str):
                j = json.loads(m)
                if j["op"] == "advertise":
                    new = []
                    for c in j["channels"]:
                        channels[c["id"]] = c
                        if c["topic"] in WANTED and c["encoding"] == "cdr":
                            sid = len(subs)
                            subs[sid] = c
                            new.append({"id": sid, "channelId": c["id"]})
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                continue
            op, sid, t = struct.unpack_from("<BIQ", m, 0)
            c = subs.get(sid)
            if op != 1 or c is None:
                out["errors"].append(f"frame op {op} on subscription {sid}")
                continue
            r = out["received"].setdefault(c["topic"], {"count": 0, "schema": c["schemaName"]})
            r["count"] += 1
            try:
                msg = TS.deserialize_cdr(bytes(m[13:]), c["schemaName"])
            except Exception as e:  # noqa: BLE001 - reported; the test fails on it
                out["errors"].append(f"{c['topic']}: {e!r}")
                continue
            r["last_time_ns"] = t
            if c["topic"] == "/joint_states":
                r["last"] = {"stamp": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                             "position": [float(x) for x in msg.position]}
            elif c["topic"] == "/robot_description":
                r["length"] = len(msg.data)
            elif c["topic"] == "/camera/color/image_raw":
                r["last"] = {"width": msg.width, "height": msg.height, "encoding": msg.encoding}
            elif c["topic"] in ("/tf", "/tf_static"):
                r["frames"] = len(msg.transforms)
            elif c["topic"] == "/arm/planned_path":
                poses = msg.poses
                r["last"] = {"frame": msg.header.frame_id, "n": len(poses),
                             "first": xyz(poses[0].pose.position) if poses else None,
                             "end": xyz(poses[-1].pose.position) if poses else None,
                             "end_stamp": (poses[-1].header.stamp.sec + poses[-1].header.stamp.nanosec * 1e-9)
                             if poses else None,
                             "stamp": msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9}
            elif c["topic"] == "/scene/markers":
                r["last"] = {"n": len(msg.markers),
                             "frames": sorted({m.header.frame_id for m in msg.markers}),
                             "bodies": {m.ns: {"type": m.type, "position": xyz(m.pose.position),
                                               "scale": xyz(m.scale), "alpha": m.color.a}
                                        for m in msg.markers if m.id == 0}}
            # Halfway, the view is told to stop sending the camera.
            if not unsubscribed and time.time() > end - seconds / 2:
                cam = [s for s, ch in subs.items() if ch["topic"] == "/camera/color/image_raw"]
                await ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": cam}))
                out["camera_unsubscribed_at"] = r.get("count") if c["topic"] == "/camera/color/image_raw" else None
                out["camera_count_at_unsubscribe"] = out["received"].get("/camera/color/image_raw", {}).get("count", 0)
                unsubscribed = True
        out["channels"] = sorted(c["topic"] for c in channels.values())
    print(json.dumps(out))


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], float(sys.argv[2])))
