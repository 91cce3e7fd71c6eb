"""In Jupyter: a notebook drives the robot through a real IPython kernel (ipykernel, run by
nbclient), and the kernel's interrupt (what the notebook's stop button sends) stops a motion
with KeyboardInterrupt and leaves the kernel and the robot usable."""

import os
import time

import nbformat
from jupyter_client.manager import KernelManager
from nbclient import NotebookClient


def _kernel():
    # ipykernel's own kernel spec: this interpreter.
    km = KernelManager(kernel_name="python3")
    km.start_kernel(env=dict(os.environ), cwd=os.getcwd())
    kc = km.client()
    kc.start_channels()
    kc.wait_for_ready(timeout=60)
    return km, kc


def _run(kc, code, timeout=120):
    """Runs `code`; returns (status, the text it printed or its error's name)."""
    msg_id = kc.execute(code)
    out, status = [], None
    deadline = time.monotonic() + timeout
    while status is None:
        msg = kc.get_iopub_msg(timeout=max(1, deadline - time.monotonic()))
        if msg["parent_header"].get("msg_id") != msg_id:
            continue
        kind, content = msg["msg_type"], msg["content"]
        if kind == "stream":
            out.append(content["text"])
        elif kind == "error":
            out.append(content["ename"])
        elif kind == "status" and content["execution_state"] == "idle":
            status = "done"
    return "".join(out)


def test_a_notebook_runs_pyrobots_program():
    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_code_cell("from ferrobot import Robot\nbot = Robot('locobot')"),
        nbformat.v4.new_code_cell("bot.arm.set_joint_positions([0.4, 0.7, -0.5, -1.4, 0.9], plan=False)"),
        nbformat.v4.new_code_cell("rgb, depth = bot.camera.get_rgb_depth()\nprint(rgb.shape, depth.dtype)"),
    ]
    NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": os.getcwd()}}).execute()
    assert nb.cells[1].outputs[0]["data"]["text/plain"] == "True"
    assert nb.cells[2].outputs[0]["text"].strip() == "(480, 640, 3) float32"


def test_the_kernels_interrupt_stops_a_motion():
    km, kc = _kernel()
    try:
        _run(kc, "from ferrobot import Robot\nbot = Robot('locobot', use_arm=False, use_camera=False, realtime=True)")
        # The cell's main thread blocks in go_to_absolute (5 m: half a minute at the wall
        # clock's pace); a thread of the cell says when the base drives, so the interrupt
        # that follows that message comes while the blocking call runs.
        msg_id = kc.execute(
            "import threading, time\n"
            "def say_when_moving():\n"
            "    while abs(bot.telemetry()['base_velocity'][0]) < 0.1:\n"
            "        time.sleep(0.005)\n"
            "    print('moving', flush=True)\n"
            "threading.Thread(target=say_when_moving, daemon=True).start()\n"
            "bot.base.go_to_absolute([5.0, 0.0, 0.0])"
        )
        error, interrupted = None, None
        while True:
            msg = kc.get_iopub_msg(timeout=120)
            if msg["parent_header"].get("msg_id") != msg_id:
                continue
            if msg["msg_type"] == "stream" and "moving" in msg["content"]["text"]:
                km.interrupt_kernel()
                interrupted = time.monotonic()
            if msg["msg_type"] == "error":
                error = msg["content"]["ename"]
                latency = time.monotonic() - interrupted
            if msg["msg_type"] == "status" and msg["content"]["execution_state"] == "idle":
                break
        assert interrupted is not None and error == "KeyboardInterrupt"
        # The error's message arrives through the kernel's sockets too: a loose bound.
        assert latency < 1.0, latency
        # The kernel lives on, the base stands still, and the robot takes the next command.
        text = _run(kc, "bot.wait(1.0)\nprint(abs(bot.telemetry()['base_velocity'][0]) < 0.01, bot.base.go_to_relative([0.0, 0.0, 0.2]))")
        assert text.strip() == "True True", text
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)
