"""PyBullet's CPU renderer on a scene exported by the `render` bench (benches/benches/render.rs).

Usage: python pybullet_render.py SCENE.json

SCENE.json (written by the bench) lists every visual shape with its world pose and colour
(boxes, cylinders, spheres and capsules as PyBullet's primitives of the same sizes, meshes as
OBJ files) and the camera: image size, the view matrix and the projection matrix (both
column-major, OpenGL conventions, built from the pinhole intrinsics). The script builds the
scene in DIRECT mode (no GUI, no GPU), then answers commands on stdin, one per line:

    render N     renders N frames with getCameraImage(..., renderer=ER_TINY_RENDERER) and
                 prints "WALL_S CPU_S" (totals over the N frames, wall clock and this thread's
                 CPU time)
    dump PREFIX  renders one frame and writes PREFIX.rgb (RGB, 8 bit, row-major) and
                 PREFIX.depth (metres, float32 little-endian, row-major), then prints "ok"
    quit         exits
"""

import json
import sys
import time

import numpy as np
import pybullet as p


def build(scene):
    for s in scene["shapes"]:
        kind = s["kind"]
        rgba = list(s["colour"]) + [1.0]
        if kind == "box":
            v = p.createVisualShape(p.GEOM_BOX, halfExtents=[x / 2 for x in s["size"]], rgbaColor=rgba)
        elif kind == "cylinder":
            v = p.createVisualShape(p.GEOM_CYLINDER, radius=s["radius"], length=s["length"], rgbaColor=rgba)
        elif kind == "sphere":
            v = p.createVisualShape(p.GEOM_SPHERE, radius=s["radius"], rgbaColor=rgba)
        elif kind == "capsule":
            v = p.createVisualShape(p.GEOM_CAPSULE, radius=s["radius"], length=s["length"], rgbaColor=rgba)
        elif kind == "mesh":
            v = p.createVisualShape(p.GEOM_MESH, fileName=s["obj"], meshScale=[1, 1, 1], rgbaColor=rgba)
        else:
            raise ValueError(f"unknown shape {kind!r}")
        if v < 0:
            raise RuntimeError(f"PyBullet refused the visual shape {s}")
        p.createMultiBody(
            baseMass=0,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=v,
            basePosition=s["position"],
            baseOrientation=s["quaternion"],
        )


def render(cam):
    return p.getCameraImage(
        cam["width"],
        cam["height"],
        viewMatrix=cam["view"],
        projectionMatrix=cam["projection"],
        renderer=p.ER_TINY_RENDERER,
    )


def main():
    with open(sys.argv[1]) as f:
        scene = json.load(f)
    p.connect(p.DIRECT)
    build(scene)
    cam = scene["camera"]
    near, far = cam["near"], cam["far"]
    for line in sys.stdin:
        cmd = line.split()
        if not cmd:
            continue
        if cmd[0] == "render":
            n = int(cmd[1])
            w0, c0 = time.perf_counter(), time.thread_time()
            for _ in range(n):
                render(cam)
            print(f"{time.perf_counter() - w0} {time.thread_time() - c0}", flush=True)
        elif cmd[0] == "dump":
            w, h, rgba, depth, _ = render(cam)
            rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3]
            rgb.tofile(cmd[1] + ".rgb")
            # The depth buffer (0-1, OpenGL's) to metres along the optical axis.
            d = np.asarray(depth, dtype=np.float64).reshape(h, w)
            z = far * near / (far - (far - near) * d)
            z[d >= 1.0] = 0.0
            z.astype("<f4").tofile(cmd[1] + ".depth")
            print("ok", flush=True)
        elif cmd[0] == "quit":
            break
    p.disconnect()


if __name__ == "__main__":
    main()
