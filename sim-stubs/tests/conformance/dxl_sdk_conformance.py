"""Drive `ferrobot-sim serve` with ROBOTIS' official Dynamixel SDK (PyPI `dynamixel-sdk`).

Usage: python dxl_sdk_conformance.py SERVO_BUS_PTY
Prints one JSON object with what the SDK saw; the Rust test judges it.
"""
import json
import sys
import time

from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, PacketHandler, PortHandler

ADDR_TORQUE_ENABLE = 64
ADDR_GOAL_POSITION = 116
ADDR_PRESENT_POSITION = 132


def main():
    port = PortHandler(sys.argv[1])
    if not port.openPort() or not port.setBaudRate(1000000):
        print(json.dumps({"error": "cannot open port"}))
        return 1
    pk = PacketHandler(2.0)
    out = {"sdk": "dynamixel_sdk", "ping": {}, "present_position_1": None}

    # 1. Ping IDs 1-9.
    for dxl_id in range(1, 10):
        model, res, err = pk.ping(port, dxl_id)
        out["ping"][str(dxl_id)] = {"ok": res == COMM_SUCCESS and err == 0, "model": model}

    # 2. Read Present Position of ID 1.
    pos, res, err = pk.read4ByteTxRx(port, 1, ADDR_PRESENT_POSITION)
    out["present_position_1"] = {"ok": res == COMM_SUCCESS and err == 0, "value": pos}

    # 3. Torque on ID 8 (pan), goal 300 ticks away, poll until it arrives (3 s at most).
    start, res, _ = pk.read4ByteTxRx(port, 8, ADDR_PRESENT_POSITION)
    goal = start + 300
    r1, e1 = pk.write1ByteTxRx(port, 8, ADDR_TORQUE_ENABLE, 1)
    r2, e2 = pk.write4ByteTxRx(port, 8, ADDR_GOAL_POSITION, goal)
    arrived_after = None
    last = start
    t0 = time.monotonic()
    while time.monotonic() - t0 < 3.0:
        p, res, err = pk.read4ByteTxRx(port, 8, ADDR_PRESENT_POSITION)
        if res == COMM_SUCCESS:
            last = p
            if abs(p - goal) <= 10:
                arrived_after = time.monotonic() - t0
                break
    # Within 10 ticks it may still be moving: wait (3 s at most) until two reads in a row
    # agree, so that the sync and single reads below compare a servo at rest.
    t1 = time.monotonic()
    while arrived_after is not None and time.monotonic() - t1 < 3.0:
        p, res, err = pk.read4ByteTxRx(port, 8, ADDR_PRESENT_POSITION)
        if res == COMM_SUCCESS:
            if p == last:
                break
            last = p
    out["move"] = {
        "writes_ok": r1 == COMM_SUCCESS and r2 == COMM_SUCCESS and e1 == 0 and e2 == 0,
        "start": start,
        "goal": goal,
        "last": last,
        "arrived_after_s": arrived_after,
    }

    # 4. Group sync read of Present Position from all nine servos.
    group = GroupSyncRead(port, pk, ADDR_PRESENT_POSITION, 4)
    for dxl_id in range(1, 10):
        group.addParam(dxl_id)
    res = group.txRxPacket()
    values = {}
    for dxl_id in range(1, 10):
        if group.isAvailable(dxl_id, ADDR_PRESENT_POSITION, 4):
            values[str(dxl_id)] = group.getData(dxl_id, ADDR_PRESENT_POSITION, 4)
    out["sync_read"] = {"ok": res == COMM_SUCCESS, "values": values}
    # The same positions, one read at a time, for comparison.
    single = {}
    for dxl_id in range(1, 10):
        p, res, err = pk.read4ByteTxRx(port, dxl_id, ADDR_PRESENT_POSITION)
        single[str(dxl_id)] = p if res == COMM_SUCCESS else None
    out["single_reads"] = single
    port.closePort()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
