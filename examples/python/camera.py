"""The pan-tilt camera: PyRobot's camera_control.py, each view saved as a PNG (colour, and
depth scaled to 0-255 over 0-4 m) instead of shown in OpenCV windows.

    python examples/python/camera.py --out-dir views
"""

import argparse
import os
import struct
import zlib

import numpy as np

from ferrobot import Robot


def write_png(path, img):
    """An 8-bit greyscale (H, W) or RGB (H, W, 3) image as a PNG, with the standard library."""
    img = np.ascontiguousarray(img, dtype=np.uint8)
    h, w = img.shape[:2]
    colour = 2 if img.ndim == 3 else 0
    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="apartment", help="the simulated scene")
    parser.add_argument("--out-dir", default="views", help="where the PNG files go")
    args = parser.parse_args()
    os.makedirs(args.out_dir, exist_ok=True)
    bot = Robot("locobot", scene=args.scene)
    bot.camera.reset()
    for i, (pan, tilt) in enumerate([[0, 0.7], [0.4, 0.4], [0.4, -0.4], [-0.4, 0.4], [-0.4, -0.4]]):
        bot.camera.set_pan_tilt(pan, tilt, wait=True)
        rgb, depth = bot.camera.get_rgb_depth()
        write_png(os.path.join(args.out_dir, "rgb_%d.png" % i), rgb)
        write_png(os.path.join(args.out_dir, "depth_%d.png" % i), np.clip(depth / 4.0 * 255, 0, 255))
        print("pan %+.1f tilt %+.1f: median depth %.2f m" % (pan, tilt, np.median(depth[depth > 0])))


if __name__ == "__main__":
    main()
