"""librealsense's software device with a synthetic scene, for `serve_realsense.py
--software-device`: a depth sensor and a colour sensor with the scene's intrinsics, depth unit
and depth-to-colour extrinsics, fed with synthetic frames into an `rs.syncer`.

Frame n (from 1) has timestamp n x 1000 / rate ms in the hardware-clock domain. Its colour
pixel at column u, row v is (u mod 256, v mod 256, (3u + 5v + 7n) mod 256). Its depth image
sees a plane z = distance + slope * y and, in front of it, a box face at z = box.z for x, y in
the box's ranges (metres, in the depth imager's optical frame: x right, y down, z forward).
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
import pyrealsense2 as rs


@dataclass
class Pinhole:
    """A pinhole camera: size (px) and intrinsics (px, pixel centres at integers)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def to_rs(self) -> Any:
        """As librealsense's `rs.intrinsics`, without distortion."""
        k = rs.intrinsics()
        k.width, k.height = self.width, self.height
        k.fx, k.fy, k.ppx, k.ppy = self.fx, self.fy, self.cx, self.cy
        k.model = rs.distortion.none
        k.coeffs = [0.0] * 5
        return k


@dataclass
class SoftwareScene:
    """What the software device shows, and its calibration.

    The colour camera has the served width and height; `colour` holds its intrinsics. The
    depth imager has its own size and intrinsics (`depth`), a depth unit (`depth_unit`, m per
    Z16 step) and a pose: `rotation` (3x3, row-major) and `translation` (m) take a point from
    the depth imager's optical frame to the colour camera's (p_colour = R p_depth + t). The
    plane and the box are in the depth imager's optical frame, metres.
    """

    colour: dict[str, float] = field(
        default_factory=lambda: {"fx": 619.8997, "fy": 620.11, "cx": 320.654, "cy": 241.1125}
    )
    depth: Pinhole = field(
        default_factory=lambda: Pinhole(424, 240, 213.0, 212.5, 211.0, 119.0)
    )
    depth_unit: float = 0.0001
    rotation: list[float] = field(default_factory=lambda: [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0])
    translation: list[float] = field(default_factory=lambda: [0.015, 0.001, 0.0])
    plane_distance: float = 1.2
    plane_slope: float = 0.25
    box_x: tuple[float, float] = (-0.10, 0.08)
    box_y: tuple[float, float] = (-0.05, 0.12)
    box_z: float = 0.7

    @staticmethod
    def from_json(text: str) -> "SoftwareScene":
        """A scene from JSON: `{"colour": {fx, fy, cx, cy}, "depth": {width, height, fx, fy,
        cx, cy}, "depth_unit", "rotation": [9], "translation": [3], "plane": {"distance",
        "slope"}, "box": {"x": [lo, hi], "y": [lo, hi], "z"}}`; a missing key keeps its
        default, an unknown one is an error."""
        d = json.loads(text)
        s = SoftwareScene()
        known = {"colour", "depth", "depth_unit", "rotation", "translation", "plane", "box"}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown keys {sorted(unknown)} (known: {sorted(known)})")
        if "colour" in d:
            s.colour = {k: float(d["colour"][k]) for k in ("fx", "fy", "cx", "cy")}
        if "depth" in d:
            k = d["depth"]
            s.depth = Pinhole(int(k["width"]), int(k["height"]), float(k["fx"]),
                              float(k["fy"]), float(k["cx"]), float(k["cy"]))
        s.depth_unit = float(d.get("depth_unit", s.depth_unit))
        s.rotation = [float(x) for x in d.get("rotation", s.rotation)]
        s.translation = [float(x) for x in d.get("translation", s.translation)]
        if len(s.rotation) != 9 or len(s.translation) != 3:
            raise ValueError("rotation needs 9 numbers (row-major), translation 3")
        plane = d.get("plane", {})
        s.plane_distance = float(plane.get("distance", s.plane_distance))
        s.plane_slope = float(plane.get("slope", s.plane_slope))
        box = d.get("box", {})
        s.box_x = tuple(float(x) for x in box.get("x", s.box_x))  # type: ignore[assignment]
        s.box_y = tuple(float(x) for x in box.get("y", s.box_y))  # type: ignore[assignment]
        s.box_z = float(box.get("z", s.box_z))
        if not (0.0 < s.depth_unit < 0.01):
            raise ValueError(f"a depth unit of {s.depth_unit} m")
        return s

    def depth_image(self) -> Any:
        """The depth imager's Z16 image (H x W uint16): the box where its face is hit, else
        the plane where it lies ahead, else 0."""
        k = self.depth
        u, v = np.meshgrid(np.arange(k.width), np.arange(k.height))
        a, b = (u - k.cx) / k.fx, (v - k.cy) / k.fy
        denom = 1.0 - self.plane_slope * b
        with np.errstate(divide="ignore"):
            z = np.where(denom > 1e-6, self.plane_distance / denom, 0.0)
        x, y = a * self.box_z, b * self.box_z
        on_box = ((x >= self.box_x[0]) & (x <= self.box_x[1])
                  & (y >= self.box_y[0]) & (y <= self.box_y[1]))
        z = np.where(on_box, self.box_z, z)
        steps = np.rint(z / self.depth_unit)
        return np.clip(steps, 0, 65535).astype(np.uint16)


def colour_pattern(width: int, height: int, n: int) -> Any:
    """Frame n's colour image (H x W x 3 uint8): (u mod 256, v mod 256, (3u + 5v + 7n) mod 256)
    at column u, row v."""
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    img = np.empty((height, width, 3), np.uint8)
    img[..., 0] = u % 256
    img[..., 1] = v % 256
    img[..., 2] = (3 * u + 5 * v + 7 * n) % 256
    return img


class SoftwareCamera:
    """librealsense's software device: a depth and a colour sensor fed with `SoftwareScene`'s
    synthetic frames at `rate` (wall clock), into an `rs.syncer`."""

    def __init__(self, scene: SoftwareScene, width: int, height: int, rate: int) -> None:
        self.scene, self.rate = scene, rate
        self.device = rs.software_device()
        self.device.register_info(rs.camera_info.name, "librealsense software device")
        self.device.register_info(rs.camera_info.serial_number, "software")
        self.device.create_matcher(rs.matchers.default)
        self.depth_sensor = self.device.add_sensor("Depth")
        self.colour_sensor = self.device.add_sensor("Color")
        self.depth_sensor.add_read_only_option(rs.option.depth_units, scene.depth_unit)
        c = scene.colour
        colour = Pinhole(width, height, c["fx"], c["fy"], c["cx"], c["cy"])
        self.depth_profile = self._stream(self.depth_sensor, rs.stream.depth, rs.format.z16,
                                          scene.depth, 2, uid=0)
        self.colour_profile = self._stream(self.colour_sensor, rs.stream.color,
                                           rs.format.rgb8, colour, 3, uid=1)
        ext = rs.extrinsics()
        r = scene.rotation
        ext.rotation = [r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]]  # column-major
        ext.translation = list(scene.translation)
        self.depth_profile.register_extrinsics_to(self.colour_profile, ext)
        self.depth_scale = self.depth_sensor.as_depth_sensor().get_depth_scale()
        self.name = "librealsense software device (synthetic plane and box)"
        self.syncer = rs.syncer(4)
        self.depth_sensor.open(self.depth_profile)
        self.colour_sensor.open(self.colour_profile)
        self.depth_sensor.start(self.syncer)
        self.colour_sensor.start(self.syncer)
        self.z16 = scene.depth_image()
        self.stop = threading.Event()
        self.producer = threading.Thread(target=self._produce, name="software frames",
                                         daemon=True)
        self.producer.start()

    def _stream(self, sensor: Any, kind: Any, fmt: Any, k: Pinhole, bpp: int,
                uid: int) -> Any:
        """Add a video stream of `k`'s size and intrinsics to `sensor`; its profile."""
        vs = rs.video_stream()
        vs.type, vs.index, vs.uid = kind, 0, uid
        vs.width, vs.height, vs.fps, vs.bpp, vs.fmt = k.width, k.height, self.rate, bpp, fmt
        vs.intrinsics = k.to_rs()
        return rs.video_stream_profile(sensor.add_video_stream(vs))

    def _frame(self, profile: Any, pixels: Any, bpp: int, n: int) -> Any:
        """A software frame of `pixels` for `profile`, number n."""
        f = rs.software_video_frame()
        f.pixels = pixels
        f.bpp = bpp
        f.stride = profile.width() * bpp
        f.timestamp = n * 1000.0 / self.rate
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = n
        f.profile = profile
        return f

    def _produce(self) -> None:
        """Inject frame n at n / rate s after the start (wall clock), depth then colour."""
        start, n = time.monotonic(), 0
        width, height = self.colour_profile.width(), self.colour_profile.height()
        while not self.stop.is_set():
            n += 1
            delay = start + n / self.rate - time.monotonic()
            if delay > 0 and self.stop.wait(delay):
                return
            rgb = colour_pattern(width, height, n)
            self.depth_sensor.on_video_frame(self._frame(self.depth_profile, self.z16, 2, n))
            self.colour_sensor.on_video_frame(self._frame(self.colour_profile, rgb, 3, n))

    def wait(self, timeout_ms: int) -> Optional[Any]:
        """The syncer's next frameset, or None."""
        ok, frames = self.syncer.try_wait_for_frames(timeout_ms)
        return frames if ok else None

    def close(self) -> None:
        """Stop feeding frames and stop the sensors."""
        self.stop.set()
        self.producer.join(timeout=2.0)
        for s in (self.depth_sensor, self.colour_sensor):
            s.stop()
            s.close()
