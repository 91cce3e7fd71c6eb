#!/usr/bin/env python3
"""Serve an Intel RealSense (a D435) on a Unix socket as Ferrobot's camera protocol.

Ferrobot's serial backend reads its camera from a Unix socket beside the serial port
(`LINK.camera`), in the protocol that `ferrobot_sim::camera_server` documents and
`ferrobot::backend::camera_socket::SocketCamera` reads. This program is that protocol's server
for a real camera, on Intel's librealsense (the `pyrealsense2` wheel):

  serve_realsense.py --socket /dev/ttyACM0.camera --description host/description/robots/locobot.toml
  serve_realsense.py --socket LINK.camera --width 640 --height 480 --rate 30 [--serial 0123456789]
  serve_realsense.py --socket /tmp/cam --software-device [--software-scene JSON]

It opens the camera (the one with `--serial`, else the first found), streams colour (RGB8) and
depth (Z16) at the robot's resolution and rate, aligns depth to colour with librealsense's
`rs.align(rs.stream.color)`, turns depth units into metres with the depth sensor's own scale
(`get_depth_scale()`), and serves:

* `info` -> one JSON line: `width`, `height`, `fx`, `fy`, `cx`, `cy` (px, the colour stream's
  intrinsics, pixel centres at integer coordinates), `rate` (Hz), and, beyond the simulator's
  server, `distortion` (`{"model": librealsense's name, "coeffs": [5 numbers]}`), `device` (a
  line naming the camera) and `depth_scale` (m per depth unit).
* `frame` -> one JSON line `{"width", "height", "frame_number", "device_time_ms", "time_domain",
  "age_us"}`, then width x height x 3 bytes of RGB (row-major, row 0 at the top), then
  width x height little-endian f32 depths in metres, aligned to colour (0 = invalid). The frame
  is the newest one that this connection has not been served yet (it waits for one, at most
  `FRAME_WAIT` seconds). `device_time_ms` is the colour frame's timestamp and `time_domain` its
  clock (`hardware_clock`, `system_time` or `global_time`); `age_us` is how long before the
  header was written the frame was taken, by the host's clock (from the timestamp in the system
  and global domains, from the frame's arrival here otherwise). There is no `time_us`: this
  server does not know the robot's clock, so the client stamps the frame with its link's clock
  less `age_us`.
* anything else -> `{"error": ...}`, and the connection stays open.

One client at a time. SIGTERM or SIGINT stops the server; the socket file is removed.

`--software-device` serves librealsense's own software device instead of a USB camera
(`software_device.py` beside this file): a depth sensor and a colour sensor with the intrinsics,
depth unit and depth-to-colour extrinsics of a synthetic scene, fed with synthetic frames
through `rs.syncer` and `rs.align`, so that alignment, depth units and intrinsics are Intel's
code, not ours.

Exit status: 0 after a signal, 2 bad arguments, 3 pyrealsense2 or numpy missing, 4 no camera
(or none with that serial number, or it cannot stream the resolution and rate), 5 the socket
path exists, 1 anything else.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import select
import signal
import socket
import stat
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any, Optional, Protocol

EXIT_USAGE = 2
EXIT_NO_MODULE = 3
EXIT_NO_CAMERA = 4
EXIT_SOCKET_EXISTS = 5

#: Longest request line, bytes (as the simulator's server).
MAX_REQUEST = 256
#: How long a `frame` request waits for a frame, s.
FRAME_WAIT = 5.0
#: How long writing one frame to the client may take, s.
SEND_TIMEOUT = 10.0
#: How often the loops look at the stop flag, s.
POLL = 0.2
#: The largest age a system or global timestamp may give, s: beyond it (a clock that jumped)
#: the frame's arrival here stands in.
MAX_TIMESTAMP_AGE = 1.0

rs: Any = None  # pyrealsense2, imported by `import_modules`
np: Any = None  # numpy, imported by `import_modules`


class Fatal(Exception):
    """An error that ends the program with a message and an exit status."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def import_modules() -> None:
    """Import pyrealsense2 and numpy into the module's globals, or say which is missing."""
    global rs, np
    try:
        import pyrealsense2 as rs_module
    except ImportError as e:
        raise Fatal(
            EXIT_NO_MODULE,
            f"pyrealsense2 (Intel's librealsense for Python) is not installed for {sys.executable} "
            f"({e}); install it with `pip install -r host/peers/realsense/requirements.txt` or "
            "`scripts/python-env.sh realsense` (PyPI has wheels for some platforms only, "
            "Linux x86-64 among them)",
        ) from e
    try:
        import numpy as np_module
    except ImportError as e:
        raise Fatal(
            EXIT_NO_MODULE, f"numpy is not installed for {sys.executable} ({e})"
        ) from e
    rs, np = rs_module, np_module


# ------------------------------------------------------------------------------------------
# Cameras


class Camera(Protocol):
    """A source of librealsense framesets (depth and colour, not yet aligned)."""

    #: The colour stream's profile (`rs.video_stream_profile`).
    colour_profile: Any
    #: The depth sensor's scale, m per Z16 step.
    depth_scale: float
    #: A line naming the camera.
    name: str

    def wait(self, timeout_ms: int) -> Optional[Any]:
        """The next frameset, or None after `timeout_ms`."""
        ...

    def close(self) -> None:
        """Stop streaming."""
        ...


class UsbCamera:
    """A RealSense on USB, through `rs.pipeline`."""

    def __init__(self, serial: Optional[str], width: int, height: int, rate: int) -> None:
        ctx = rs.context()
        found = {d.get_info(rs.camera_info.serial_number): d for d in ctx.query_devices()}
        if not found:
            raise Fatal(EXIT_NO_CAMERA, "no RealSense device found (is it plugged in, on USB 3, "
                        "and readable: librealsense's udev rules?)")
        if serial is not None and serial not in found:
            raise Fatal(EXIT_NO_CAMERA, f"no RealSense device with serial number {serial} "
                        f"(found: {', '.join(sorted(found))})")
        serial = serial if serial is not None else sorted(found)[0]
        dev = found[serial]
        info = rs.camera_info
        self.name = (f"{dev.get_info(info.name)} serial {serial} firmware "
                     f"{dev.get_info(info.firmware_version)}")
        cfg = rs.config()
        cfg.enable_device(serial)
        cfg.enable_stream(rs.stream.depth, width, height, rs.format.z16, rate)
        cfg.enable_stream(rs.stream.color, width, height, rs.format.rgb8, rate)
        self.pipeline = rs.pipeline(ctx)
        try:
            started = self.pipeline.start(cfg)
        except RuntimeError as e:
            raise Fatal(EXIT_NO_CAMERA, f"{self.name} cannot stream colour and depth at "
                        f"{width}x{height} and {rate} Hz: {e}") from e
        self.depth_scale = started.get_device().first_depth_sensor().get_depth_scale()
        self.colour_profile = started.get_stream(rs.stream.color).as_video_stream_profile()

    def wait(self, timeout_ms: int) -> Optional[Any]:
        """The pipeline's next frameset, or None."""
        ok, frames = self.pipeline.try_wait_for_frames(timeout_ms)
        return frames if ok else None

    def close(self) -> None:
        """Stop the pipeline."""
        self.pipeline.stop()


# ------------------------------------------------------------------------------------------
# Frames: aligned, in metres, kept for the clients


@dataclass
class Frame:
    """One aligned frame, ready to send."""

    width: int
    height: int
    frame_number: int
    device_time_ms: float
    time_domain: str
    #: When it reached this program (time.monotonic(), s).
    arrival: float
    rgb: bytes
    depth: bytes

    def age_us(self, now_wall: float, now_mono: float) -> int:
        """How long ago the frame was taken, µs: from its timestamp when that is on the host's
        clock (system or global domain) and plausible, else from its arrival here."""
        if self.time_domain in ("system_time", "global_time"):
            age = now_wall - self.device_time_ms / 1000.0
            if 0.0 <= age <= MAX_TIMESTAMP_AGE:
                return round(age * 1e6)
        return max(0, round((now_mono - self.arrival) * 1e6))


DOMAINS = {"hardware_clock", "system_time", "global_time"}


class Capture:
    """Reads a camera's framesets on a thread, aligns depth to colour with `rs.align`, converts
    it to metres, and keeps the newest frame."""

    def __init__(self, camera: Camera) -> None:
        self.camera = camera
        self.align = rs.align(rs.stream.color)
        self.newest: Optional[Frame] = None
        self.failure: Optional[str] = None
        self.cv = threading.Condition()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="capture", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        """Capture until stopped; an exception is kept for the clients to hear."""
        try:
            while not self.stop.is_set():
                frames = self.camera.wait(int(POLL * 1000))
                frame = self._convert(frames) if frames is not None else None
                if frame is not None:
                    with self.cv:
                        self.newest = frame
                        self.cv.notify_all()
        except Exception as e:  # noqa: BLE001: reported to every client, and on stderr
            print(f"serve_realsense: capture failed: {e}", file=sys.stderr, flush=True)
            with self.cv:
                self.failure = str(e)
                self.cv.notify_all()

    def _convert(self, frames: Any) -> Optional[Frame]:
        """The frameset aligned and converted, or None when it lacks depth or colour."""
        if not (frames.get_depth_frame() and frames.get_color_frame()):
            return None
        arrival = time.monotonic()
        aligned = self.align.process(frames)
        depth, colour = aligned.get_depth_frame(), aligned.get_color_frame()
        if not (depth and colour):
            return None
        rgb = np.ascontiguousarray(np.asanyarray(colour.get_data()), dtype=np.uint8)
        z16 = np.asanyarray(depth.get_data())
        metres = (z16.astype(np.float64) * self.camera.depth_scale).astype("<f4")
        domain = str(colour.get_frame_timestamp_domain()).rsplit(".", 1)[-1]
        return Frame(
            width=colour.get_width(),
            height=colour.get_height(),
            frame_number=int(colour.get_frame_number()),
            device_time_ms=float(colour.get_timestamp()),
            time_domain=domain if domain in DOMAINS else "other",
            arrival=arrival,
            rgb=rgb.tobytes(),
            depth=metres.tobytes(),
        )

    def next_after(self, served: int, timeout: float, stop: threading.Event) -> Frame | str:
        """The newest frame if its number is not `served` (the one last sent), else the next,
        waiting at most `timeout` s (or until `stop`); an error message otherwise."""
        deadline = time.monotonic() + timeout
        with self.cv:
            while True:
                if self.failure is not None:
                    return f"the camera failed: {self.failure}"
                if self.newest is not None and self.newest.frame_number != served:
                    return self.newest
                left = deadline - time.monotonic()
                if left <= 0 or stop.is_set():
                    return f"no new frame from the camera in {timeout:g} s"
                self.cv.wait(min(left, POLL))

    def close(self) -> None:
        """Stop the thread."""
        self.stop.set()
        self.thread.join(timeout=2.0)


# ------------------------------------------------------------------------------------------
# The socket


def info_reply(camera: Camera) -> dict[str, Any]:
    """The `info` answer: the colour stream's intrinsics and rate, its distortion, the device."""
    k = camera.colour_profile.get_intrinsics()
    model = str(k.model).rsplit(".", 1)[-1]
    return {
        "width": k.width, "height": k.height, "fx": k.fx, "fy": k.fy, "cx": k.ppx, "cy": k.ppy,
        "rate": float(camera.colour_profile.fps()),
        "distortion": {"model": model, "coeffs": [float(c) for c in k.coeffs]},
        "device": camera.name,
        "depth_scale": camera.depth_scale,
    }


def send_json(conn: socket.socket, value: dict[str, Any]) -> None:
    """One JSON line."""
    conn.sendall((json.dumps(value) + "\n").encode())


class Client:
    """One connection: reads request lines, answers them."""

    def __init__(self, conn: socket.socket, capture: Capture, info: dict[str, Any]) -> None:
        self.conn, self.capture, self.info = conn, capture, info
        self.buffer = b""
        self.served = -1

    def serve(self, stop: threading.Event) -> None:
        """Answer until the client leaves, misbehaves, or `stop` is set."""
        while not stop.is_set():
            line = self._line(stop)
            if line is None:
                return
            request = line.strip()
            self.conn.settimeout(SEND_TIMEOUT)
            if request == b"info":
                send_json(self.conn, self.info)
            elif request == b"frame":
                self._frame(stop)
            else:
                send_json(self.conn, {"error": "unknown request; say `info` or `frame`"})

    def _line(self, stop: threading.Event) -> Optional[bytes]:
        """The next request line, or None when the client left or sent too long a line."""
        while b"\n" not in self.buffer:
            if len(self.buffer) > MAX_REQUEST or stop.is_set():
                return None
            ready, _, _ = select.select([self.conn], [], [], POLL)
            if not ready:
                continue
            chunk = self.conn.recv(MAX_REQUEST)
            if not chunk:
                return None
            self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        return line if len(line) <= MAX_REQUEST else None

    def _frame(self, stop: threading.Event) -> None:
        """Send the next frame not yet served, or an error line."""
        frame = self.capture.next_after(self.served, FRAME_WAIT, stop)
        if isinstance(frame, str):
            send_json(self.conn, {"error": frame})
            return
        self.served = frame.frame_number
        header = {
            "width": frame.width, "height": frame.height, "frame_number": frame.frame_number,
            "device_time_ms": frame.device_time_ms, "time_domain": frame.time_domain,
            "age_us": frame.age_us(time.time(), time.monotonic()),
        }
        send_json(self.conn, header)
        self.conn.sendall(frame.rgb)
        self.conn.sendall(frame.depth)


def refuse_existing(path: str) -> None:
    """Fail if `path` exists: a socket is never replaced."""
    if os.path.lexists(path):
        raise Fatal(EXIT_SOCKET_EXISTS, f"{path} exists: nothing is replaced (remove it if no "
                    "server uses it)")


def bind(path: str) -> tuple[socket.socket, int]:
    """A listening Unix socket at `path` (which must not exist) and its inode."""
    refuse_existing(path)
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen(1)
    listener.settimeout(POLL)
    return listener, os.stat(path).st_ino


def remove_socket(path: str, inode: int) -> None:
    """Remove the socket file at `path` if it is still the one this server made."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISSOCK(st.st_mode) and st.st_ino == inode:
        os.unlink(path)


def serve(path: str, camera: Camera, stop: threading.Event) -> None:
    """Serve `camera` at `path` until `stop` is set; the socket file is removed at the end."""
    capture = Capture(camera)
    info = info_reply(camera)
    listener, inode = bind(path)
    try:
        print(f"serve_realsense: {camera.name}, colour {info['width']}x{info['height']} at "
              f"{info['rate']:g} Hz, on {path}", flush=True)
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except socket.timeout:
                continue
            with conn:
                try:
                    Client(conn, capture, info).serve(stop)
                except OSError:
                    pass  # the client went away mid-answer
    finally:
        listener.close()
        remove_socket(path, inode)
        capture.close()


# ------------------------------------------------------------------------------------------
# Command line


def camera_section(path: str) -> dict[str, Any]:
    """The `[camera]` section of a robot description (TOML)."""
    import tomllib

    with open(path, "rb") as f:
        section = tomllib.load(f).get("camera")
    if not isinstance(section, dict):
        raise Fatal(EXIT_USAGE, f"{path} has no [camera] section")
    return section


def arguments(argv: Optional[list[str]] = None) -> argparse.Namespace:
    """The command line, with width, height and rate filled from `--description`."""
    p = argparse.ArgumentParser(
        description="Serve a RealSense on a Unix socket in Ferrobot's camera protocol.")
    p.add_argument("--socket", required=True, help="socket path, e.g. /dev/ttyACM0.camera")
    p.add_argument("--description", help="a robot description (TOML) whose [camera] section "
                   "gives width, height and rate")
    p.add_argument("--width", type=int, help="colour and depth width, px")
    p.add_argument("--height", type=int, help="colour and depth height, px")
    p.add_argument("--rate", type=float, help="frames per second")
    p.add_argument("--serial", help="the camera's serial number (default: the first found)")
    p.add_argument("--software-device", action="store_true",
                   help="serve librealsense's software device with a synthetic scene")
    p.add_argument("--software-scene", help="the software device's scene, as JSON "
                   "(SoftwareScene.from_json)")
    a = p.parse_args(argv)
    if a.description:
        section = camera_section(a.description)
        a.width = a.width if a.width is not None else section.get("width")
        a.height = a.height if a.height is not None else section.get("height")
        a.rate = a.rate if a.rate is not None else section.get("rate", 30.0)
    if a.width is None or a.height is None or a.rate is None:
        p.error("give --width, --height and --rate, or --description")
    if not (a.width > 0 and a.height > 0 and a.rate > 0 and float(a.rate).is_integer()):
        p.error(f"{a.width}x{a.height} at {a.rate} Hz: a RealSense needs a whole rate")
    if a.software_scene and not a.software_device:
        p.error("--software-scene needs --software-device")
    return a


def open_camera(a: argparse.Namespace) -> Camera:
    """The camera the arguments choose."""
    rate = int(a.rate)
    if a.software_device:
        from software_device import SoftwareCamera, SoftwareScene

        try:
            scene = SoftwareScene.from_json(a.software_scene) if a.software_scene \
                else SoftwareScene()
        except (ValueError, KeyError, TypeError) as e:
            raise Fatal(EXIT_USAGE, f"--software-scene: {e}") from e
        return SoftwareCamera(scene, a.width, a.height, rate)
    return UsbCamera(a.serial, a.width, a.height, rate)


def warn_distortion(camera: Camera) -> None:
    """Say on stderr when the colour stream's distortion is not zero: Ferrobot's geometry is a
    pinhole's."""
    coeffs = [float(c) for c in camera.colour_profile.get_intrinsics().coeffs]
    if any(not math.isclose(c, 0.0, abs_tol=1e-9) for c in coeffs):
        print(f"serve_realsense: warning: the colour stream's distortion is {coeffs}; "
              "Ferrobot projects with a pinhole and ignores it", file=sys.stderr, flush=True)


def main(argv: Optional[list[str]] = None) -> int:
    """Run the server; the exit status."""
    a = arguments(argv)
    stop = threading.Event()

    def handler(_signal: int, _frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
    camera: Optional[Camera] = None
    try:
        refuse_existing(a.socket)
        import_modules()
        camera = open_camera(a)
        warn_distortion(camera)
        serve(a.socket, camera, stop)
        return 0
    except Fatal as e:
        print(f"serve_realsense: {e}", file=sys.stderr, flush=True)
        return e.status
    finally:
        if camera is not None:
            camera.close()


if __name__ == "__main__":
    sys.exit(main())
