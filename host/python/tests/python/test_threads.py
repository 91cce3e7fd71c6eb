"""The robot from several Python threads: blocking calls release the GIL (other threads run
meanwhile), and calls from threads interleave safely on one robot."""

import threading

import numpy as np

from ferrobot import Robot


def test_blocking_calls_release_the_gil():
    bot = Robot("locobot", use_camera=False, realtime=True)
    ticks = 0
    stop = threading.Event()

    def count():
        nonlocal ticks
        while not stop.is_set():
            ticks += 1

    t = threading.Thread(target=count)
    t.start()
    try:
        bot.base.go_to_relative([0.0, 0.0, 0.5])  # about 1 s of wall time, paced
    finally:
        stop.set()
        t.join()
    # A thread held back by the GIL would count only in the interpreter's switch intervals
    # (5 ms each) while the call ran; free, it counts hundreds of thousands of times.
    assert ticks > 100_000, ticks


def test_threads_share_one_robot():
    bot = Robot("locobot", scene="tabletop")
    errors = []
    frames = []

    def look():
        try:
            for _ in range(5):
                frames.append(bot.camera.get_rgb_depth()[1])
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    def move():
        try:
            for q in ([0.3, 0.2, 0.1, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0]):
                bot.arm.set_joint_positions(q, plan=False)
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=look), threading.Thread(target=move)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert len(frames) == 5 and all(f.shape == (480, 640) for f in frames)
    assert np.allclose(bot.arm.get_joint_angles(), 0.0, atol=0.02)
