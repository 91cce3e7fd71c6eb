"""Ctrl-C during a blocking call: the motion stops and KeyboardInterrupt is raised within
100 ms of wall time, and the robot takes the next command (nothing latches).

Each case runs in a child interpreter on a simulator paced to the wall clock
(``realtime=True``), so that the motion is under way when the signal comes: the child starts
a thread that sends itself SIGINT once the base is moving (it polls the robot's telemetry, not
a sleep), notes the wall time, and the main thread measures when the KeyboardInterrupt
arrives."""

import json
import os
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent(
    """
    import json, os, signal, sys, threading, time
    import numpy as np
    from ferrobot import Robot

    bot = Robot("locobot", use_arm=False, use_camera=False, realtime=True)
    sent = {}

    def interrupt():
        # Once the base drives at speed (the telemetry's), Ctrl-C.
        while abs(bot.telemetry()["base_velocity"][0]) < 0.15:
            time.sleep(0.005)
        sent["t"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt, daemon=True).start()
    try:
        bot.base.go_to_absolute([5.0, 0.0, 0.0])
        print(json.dumps({"interrupted": False}))
        sys.exit(0)
    except KeyboardInterrupt:
        latency = time.monotonic() - sent["t"]
    before = np.array(bot.base.get_state())
    bot.wait(1.0)
    after = np.array(bot.base.get_state())
    speed = bot.telemetry()["base_velocity"][0]
    # Nothing latched: the next motion runs.
    bot.base.go_to_relative([0.0, 0.0, 0.3])
    print(json.dumps({
        "interrupted": True,
        "latency": latency,
        "drift": float(np.linalg.norm(after[:2] - before[:2])),
        "speed": speed,
        "travelled": float(before[0]),
    }))
    """
)


def test_ctrl_c_stops_go_to_absolute_within_100_ms():
    out = subprocess.run(
        [sys.executable, "-c", CHILD],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ),
    )
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["interrupted"], "the motion ended before the signal"
    assert r["latency"] < 0.1, r
    # The base had started (it was 5 m from its goal) and stopped: no more than its braking
    # distance after the interrupt, and standing still a second later.
    assert 0.0 < r["travelled"] < 4.0, r
    assert r["drift"] < 0.05 and abs(r["speed"]) < 0.01, r
