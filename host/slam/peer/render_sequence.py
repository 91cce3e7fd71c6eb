#!/usr/bin/env python3
"""Render an RGB-D sequence with PyBullet's TinyRenderer, a renderer that is not the project's,
in the TUM RGB-D layout that `ferrobot slam --dataset` reads: rgb/ and depth/ PNGs (8-bit colour;
16-bit depth at 5000 units per metre), rgb.txt, depth.txt, groundtruth.txt (the camera's optical
frame in the world: x right, y down, z forward; TUM's `t tx ty tz qx qy qz qw`) and camera.yaml
(a RealSense D435's intrinsics at 640x480), and events.txt (each event's frames).

The world: a 7 m x 7 m room with 2.5 m walls and boxes on the floor, each with a texture of its
own drawn here (blobs, stripes and noise of colours unlike the project's scenes). The camera
rides 0.6 m above the floor on an arc of 4.7 m around the room's middle, looking inward, at
30 Hz, with no wheel odometry. Kinds of sequence (--kind):

  arc         the path above;
  blank-wall  the arc, but in the middle the camera stops, turns round to face a bare board
              0.5 m behind it for 2 s, and turns back;
  fast-turn   the arc, with a full turn on the spot at 3 rad/s in the middle;
  blur        the arc, each frame the mean of 5 renders across its exposure;
  lighting    the arc, with the light switched to a dim, coloured one halfway;
  holes       the arc, with a third of every depth image lost in blobs (the D435's holes);
  edges       the arc with all of the above one after the other: the bare wall for 2 s
              (frames 100-190), a full turn (230-292), blur (320-360), the light dimmed (from
              380), depth holes (420-480).

Usage: render_sequence.py --out DIR [--kind arc] [--frames 600] [--seed 1]
"""

import argparse
import math
import os
import struct
import zlib

import numpy as np
import pybullet as p

WIDTH, HEIGHT = 640, 480
FX, FY, CX, CY = 619.8997, 620.1100, 320.6540, 241.1125  # D435 colour, 640x480
DEPTH_FACTOR = 5000.0
NEAR, FAR = 0.1, 20.0
RATE = 30.0
HEIGHT_CAM = 0.6
ARC_LENGTH = 4.7
ARC_RADIUS = 1.6


def write_png(path, img):
    """A PNG of `img`: HxWx3 uint8 (colour) or HxW uint16 (grey, big-endian as PNG wants)."""
    if img.dtype == np.uint8 and img.ndim == 3:
        colour, depth, rows = 2, 8, img
    elif img.dtype == np.uint16 and img.ndim == 2:
        colour, depth, rows = 0, 16, img.astype(">u2")
    else:
        raise ValueError("unsupported image")
    h, w = img.shape[:2]
    raw = b"".join(b"\x00" + rows[y].tobytes() for y in range(h))

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 1))
                + chunk(b"IEND", b""))


def texture(rng, path, kind, size=512):
    """A texture of the given kind, written to `path`: a PNG PyBullet loads."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float32) / size
    base = rng.uniform(40, 215, 3)
    img = np.zeros((size, size, 3), np.float32) + base
    if kind == "blobs":
        for _ in range(90):
            cx, cy, r = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.01, 0.07)
            mask = (x - cx) ** 2 + (y - cy) ** 2 < r * r
            img[mask] = rng.uniform(0, 255, 3)
    elif kind == "stripes":
        for _ in range(40):
            a, w, off = rng.uniform(0, math.pi), rng.uniform(0.004, 0.02), rng.uniform(0, 1.5)
            d = (x * math.cos(a) + y * math.sin(a) - off) % 0.25
            img[d < w] = rng.uniform(0, 255, 3)
    elif kind == "plain":
        pass
    # Fine noise everywhere but on a plain wall.
    if kind != "plain":
        img += rng.normal(0, 18, (size, size, 1))
    write_png(path, np.clip(img, 0, 255).astype(np.uint8))


def build_world(rng, tmp, partition=False, board=None):
    """The room and its boxes (and, with `partition`, a wall through the room's middle with a
    box before it, which the camera passes close; with `board` = (x, y, yaw), a bare board
    standing there across the heading yaw, which fills the view of a camera turned to it)."""
    p.resetSimulation()
    half = 3.5

    def box(size, pos, tex):
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[s / 2 for s in size])
        body = p.createMultiBody(baseMass=0, baseVisualShapeIndex=vis, basePosition=pos)
        p.changeVisualShape(body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1])
        return body

    def tex(kind):
        path = os.path.join(tmp, f"tex{len(os.listdir(tmp))}.png")
        texture(rng, path, kind)
        return p.loadTexture(path)

    box([2 * half, 2 * half, 0.02], [0, 0, -0.01], tex("blobs"))
    walls = [([2 * half, 0.1, 2.5], [0, half, 1.25]), ([2 * half, 0.1, 2.5], [0, -half, 1.25]),
             ([0.1, 2 * half, 2.5], [half, 0, 1.25])]
    for size, pos in walls:
        box(size, pos, tex(rng.choice(["blobs", "stripes"])))
    box([0.1, 2 * half, 2.5], [-half, 0, 1.25], tex("plain"))
    if board is not None:
        x, y, yaw = board
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.01, 1.0, 1.0])
        body = p.createMultiBody(baseMass=0, baseVisualShapeIndex=vis, basePosition=[x, y, 1.0],
                                 baseOrientation=p.getQuaternionFromEuler([0, 0, yaw]))
        p.changeVisualShape(body, -1, textureUniqueId=tex("plain"), rgbaColor=[1, 1, 1, 1])
    if partition:
        box([0.08, 1.6, 1.8], [0.0, 0.0, 0.9], tex(rng.choice(["blobs", "stripes"])))
        box([0.35, 0.4, 0.5], [0.3, 0.2, 0.25], tex("blobs"))
    # Boxes around the room's middle, where the camera looks.
    for k in range(0 if partition else 7):
        a = 2 * math.pi * k / 7 + rng.uniform(-0.2, 0.2)
        r = rng.uniform(0.2, 0.7)
        s = [rng.uniform(0.2, 0.5), rng.uniform(0.2, 0.5), rng.uniform(0.2, 0.9)]
        box(s, [r * math.cos(a), r * math.sin(a), s[2] / 2], tex(rng.choice(["blobs", "stripes"])))
    # Boxes along the three textured walls.
    for k in range(6):
        s = [rng.uniform(0.3, 0.6), rng.uniform(0.3, 0.6), rng.uniform(0.3, 1.2)]
        along = rng.uniform(-half + 0.6, half - 0.6)
        side = k % 3
        pos = [[along, half - 0.5, s[2] / 2], [along, -half + 0.5, s[2] / 2],
               [half - 0.5, along, s[2] / 2]][side]
        box(s, pos, tex(rng.choice(["blobs", "stripes"])))


def events(kind, n):
    """Frame windows [first, last) of each event of a sequence of `kind` and `n` frames."""
    mid = n // 2
    turn = int(RATE * 2 * math.pi / 3.0)
    single = {
        "blank-wall": {"blank": (mid - 45, mid + 45)},
        "fast-turn": {"turn": (mid, mid + turn)},
        "blur": {"blur": (1, n - 1)},
        "lighting": {"dim": (mid, n)},
        "holes": {"holes": (0, n)},
    }
    if kind == "edges":
        # All of them, one after the other, in one sequence.
        return {"blank": (100, 190), "turn": (230, 230 + turn), "blur": (320, 360),
                "dim": (380, n), "holes": (420, 480)}
    return single.get(kind, {})


def arc_angle(n, radius, k):
    """The angle (rad, about the room's middle) of the camera's position after k of the n
    frames that move along the arc."""
    sweep = ARC_LENGTH / radius
    return math.pi / 2 - sweep / 2 + sweep * k / max(n - 1, 1)


def within(ev, name, i):
    a, b = ev.get(name, (0, 0))
    return a <= i < b


def camera_path(kind, n, radius):
    """The optical frame's poses: a list of (time, position, R) with R's columns the camera's
    x, y, z (right, down, forward). The camera stands still on the arc while it turns to the
    bare board and back, and while it turns round on the spot."""
    poses = []
    ev = events(kind, n)
    still = [within(ev, "blank", i) or within(ev, "turn", i) for i in range(n)]
    moving = n - sum(still)
    k = 0
    for i in range(n):
        t = i / RATE
        # Along the arc, centred on +y, looking inward.
        phi = arc_angle(moving, radius, k)
        k += 0 if still[i] else 1
        pos = np.array([radius * math.cos(phi), radius * math.sin(phi), HEIGHT_CAM])
        yaw = phi + math.pi
        if within(ev, "blank", i):
            # Turn round to face the bare board behind it over 0.5 s, hold it 2 s, turn back
            # over 0.5 s.
            a, b = ev["blank"]
            w = min(i - a, 15, b - 1 - i) / 15.0
            yaw += w * math.pi
        if within(ev, "turn", i):
            yaw += 3.0 * (i - ev["turn"][0]) / RATE
        fwd = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        down = np.array([0.0, 0.0, -1.0])
        poses.append((t, pos, np.column_stack([right, down, fwd])))
    return poses


# The last render's key and result: a camera standing still (facing the bare board for 2 s)
# renders the same view frame after frame.
_last = [None, None]


def render(pos, R, light):
    """Colour (HxWx3 float32) and depth (HxW, m, 0 where nothing is hit) from the optical
    frame at `pos` with axes `R` under `light`; a view equal to the last one is not redrawn."""
    key = (pos.tobytes(), R.tobytes(), tuple(light["dir"]), tuple(light["colour"]))
    if _last[0] != key:
        _last[0], _last[1] = key, _draw(pos, R, light)
    rgb, depth = _last[1]
    return rgb.copy(), depth.copy()


def _draw(pos, R, light):
    fwd, down = R[:, 2], R[:, 1]
    view = p.computeViewMatrix(pos.tolist(), (pos + fwd).tolist(), (-down).tolist())
    # OpenGL projection from the pinhole (principal point off centre as the D435's).
    proj = [2 * FX / WIDTH, 0, 0, 0,
            0, 2 * FY / HEIGHT, 0, 0,
            1 - 2 * CX / WIDTH, 2 * CY / HEIGHT - 1, -(FAR + NEAR) / (FAR - NEAR), -1,
            0, 0, -2 * FAR * NEAR / (FAR - NEAR), 0]
    _, _, rgba, zbuf, _ = p.getCameraImage(WIDTH, HEIGHT, view, proj, renderer=p.ER_TINY_RENDERER,
                                           lightDirection=light["dir"], lightColor=light["colour"],
                                           lightAmbientCoeff=light["ambient"],
                                           lightDiffuseCoeff=light["diffuse"], shadow=0)
    rgb = np.reshape(np.asarray(rgba, np.uint8), (HEIGHT, WIDTH, 4))[:, :, :3].astype(np.float32)
    z = np.reshape(np.asarray(zbuf, np.float32), (HEIGHT, WIDTH))
    depth = FAR * NEAR / (FAR - (FAR - NEAR) * z)
    depth[z >= 1.0] = 0.0
    return rgb, depth


def quat(R):
    """[x, y, z, w] of a rotation matrix."""
    w = math.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return [x / n, y / n, z / n, w / n]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--kind", default="arc",
                    choices=["arc", "blank-wall", "fast-turn", "blur", "lighting", "holes", "edges"])
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radius", type=float, default=ARC_RADIUS, help="the arc's radius, m")
    ap.add_argument("--partition", action="store_true",
                    help="a wall through the room's middle, a box before it")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    out = a.out
    for d in ("rgb", "depth", "textures"):
        os.makedirs(os.path.join(out, d), exist_ok=True)
    p.connect(p.DIRECT)
    ev = events(a.kind, a.frames)
    board = None
    if "blank" in ev:
        # 0.5 m behind where the camera stands while it looks at it.
        poses = camera_path(a.kind, a.frames, a.radius)
        x, y = poses[ev["blank"][0]][1][:2]
        phi = math.atan2(y, x)
        r = a.radius + 0.5
        board = (r * math.cos(phi), r * math.sin(phi), phi)
    build_world(rng, os.path.join(out, "textures"), a.partition, board)
    bright = {"dir": [1.0, 0.6, 2.0], "colour": [1, 1, 1], "ambient": 0.6, "diffuse": 0.4}
    dim = {"dir": [-1.0, -0.3, 1.0], "colour": [1.0, 0.75, 0.5], "ambient": 0.35, "diffuse": 0.3}
    poses = camera_path(a.kind, a.frames, a.radius)
    rgb_list, depth_list, gt = [], [], []
    for i, (t, pos, R) in enumerate(poses):
        light = dim if within(ev, "dim", i) else bright
        if within(ev, "blur", i) and 0 < i < len(poses) - 1:
            # The exposure: the mean of 5 renders from the poses between the neighbouring
            # frames' (position and heading).
            # The middle of the exposure is the frame's own pose, that of its depth image.
            middle, depth = render(pos, R, light)
            acc = np.zeros((HEIGHT, WIDTH, 3), np.float32)
            (_, p0, r0), (_, p1, r1) = poses[i - 1], poses[i + 1]
            for f in np.linspace(-0.5, 0.5, 5):
                if f == 0.0:
                    acc += middle
                    continue
                q = pos + f * (p1 - p0) / 2
                rr = R + f * (r1 - r0) / 2
                u, _, vt = np.linalg.svd(rr)
                c, _ = render(q, u @ vt, light)
                acc += c
            colour = acc / 5
        else:
            colour, depth = render(pos, R, light)
        if within(ev, "holes", i):
            holes = np.zeros((HEIGHT, WIDTH), bool)
            yy, xx = np.ogrid[:HEIGHT, :WIDTH]
            while holes.mean() < 0.33:
                cy, cx = rng.integers(0, HEIGHT), rng.integers(0, WIDTH)
                r = rng.integers(10, 60)
                holes |= (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
            depth[holes] = 0.0
        name = f"{t:.6f}.png"
        write_png(os.path.join(out, "rgb", name), np.clip(colour, 0, 255).astype(np.uint8))
        d16 = np.clip(np.round(depth * DEPTH_FACTOR), 0, 65535).astype(np.uint16)
        write_png(os.path.join(out, "depth", name), d16)
        rgb_list.append(f"{t:.6f} rgb/{name}")
        depth_list.append(f"{t:.6f} depth/{name}")
        qx, qy, qz, qw = quat(R)
        gt.append(f"{t:.6f} {pos[0]:.6f} {pos[1]:.6f} {pos[2]:.6f} {qx:.7f} {qy:.7f} {qz:.7f} {qw:.7f}")
    header = "# rendered by PyBullet's TinyRenderer (host/slam/peer/render_sequence.py)\n"
    for name, lines in (("rgb.txt", rgb_list), ("depth.txt", depth_list), ("groundtruth.txt", gt)):
        with open(os.path.join(out, name), "w") as f:
            f.write(header + "\n".join(lines) + "\n")
    with open(os.path.join(out, "events.txt"), "w") as f:
        f.write("# event first_frame end_frame (the frames [first, end) of each event)\n")
        f.writelines(f"{name} {a} {b}\n" for name, (a, b) in sorted(ev.items(), key=lambda e: e[1]))
    with open(os.path.join(out, "camera.yaml"), "w") as f:
        f.write(f"fx: {FX}\nfy: {FY}\ncx: {CX}\ncy: {CY}\nwidth: {WIDTH}\nheight: {HEIGHT}\n"
                f"depth_factor: {DEPTH_FACTOR}\n")
    p.disconnect()


if __name__ == "__main__":
    main()
