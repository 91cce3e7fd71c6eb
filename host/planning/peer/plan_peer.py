#!/usr/bin/env python3
"""Peer for `ferrobot bench plan`: OMPL's RRTConnect on the same problems, and an FCL re-check.

Reads the export that `ferrobot bench plan` writes (JSON: robot, urdf, root_link, joints,
fixed_joints, moving_links, self_pairs, attached, resolution_m, objects, problems with start,
goal and path; only joints, objects and problems' start/goal are required: then the robot's
URDF comes from `robot` or --urdf, moving links are those below the first planned joint, no
self pair is checked, other joints are at 0) and either

  plan_peer.py ompl EXPORT.json [--time-limit 1.0] [--simplify] [--seed 1] [--paths-out OUT.json]
      plans every problem with OMPL's RRTConnect in a RealVectorStateSpace bounded by the URDF's
      joint limits (a continuous joint gets [-pi, pi]); a state is valid when FCL finds no
      contact between the moving links (and attached objects) and the objects, nor within the
      self pairs; OMPL checks edges every `step` rad (joint-space Euclidean) with
      step = resolution_m / |reach|_2, reach_i being a bound on how fast joint i moves any
      robot point (m/rad, see `joint_reach`), so that no point moves more than resolution_m
      between checked states. With --simplify the solution is simplified (SimpleSetup's
      simplifySolution, i.e. PathSimplifier.simplifyMax) inside the timed region. Prints one
      JSON object; --paths-out also writes the export with OMPL's paths, for `check`.

  plan_peer.py check EXPORT.json [--step 0.001]
      re-checks every path in the export: each edge a -> b is cut into
      ceil(sum_i reach_i |b_i - a_i| / step) equal parts, so that no robot point moves more
      than --step metres between checked states; every state is checked exactly with FCL (no
      margin); path ends must equal start/goal within 1e-6 and every state must lie within
      the joint limits. Prints one JSON object, exits 1 when any collision or error is found.

Run with the venv that `scripts/python-env.sh plan` makes:
  target/py-venv/bin/python host/planning/peer/plan_peer.py check host/planning/peer/example_export.json

Relative paths in an export (urdf, meshes) are taken relative to the export file. Geometry:
URDF collision box/cylinder/sphere/mesh (a mesh, OBJ or STL, becomes the convex hull of its
vertices); objects box/cylinder/sphere/capsule/mesh (a mesh object is its triangle mesh by
default, as MoveIt has it, so that only surfaces touch; --object-mesh hull takes its convex
hull). Timing covers solve (and simplify) only; the validity checks are Python callbacks
(about 0.1 ms a state), which dominate OMPL's time: per_problem reports their number.
"""

import argparse
import json
import math
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import fcl
import numpy as np

ROBOTS_DIR = Path(__file__).resolve().parents[2] / "description" / "robots"
END_TOLERANCE = 1e-6
LIMIT_TOLERANCE = 1e-9


# ---------------------------------------------------------------------------------------------
# Poses


def rpy_matrix(roll, pitch, yaw):
    """URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                              math.sin(pitch), math.cos(yaw), math.sin(yaw))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def quat_matrix(q):
    """Rotation matrix of a quaternion given as [x, y, z, w] (normalised here)."""
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def pose(rotation, translation):
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


def axis_rotation(axis, angle):
    """Rodrigues: rotation by `angle` about the unit vector `axis`."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    t = 1 - c
    return np.array([[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
                     [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
                     [t * x * z - s * y, t * y * z + s * x, t * z * z + c]])


def floats(text, default):
    return [float(v) for v in text.split()] if text else list(default)


# ---------------------------------------------------------------------------------------------
# Robot description


@dataclass
class Shape:
    kind: str  # box | cylinder | sphere | capsule | mesh
    size: list  # box: full extents; cylinder/capsule: [radius, length]; sphere: [radius]
    mesh: Path = None
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))


@dataclass
class Element:
    """One collision shape: `name` for reports, `link` it moves with, pose in that link."""
    name: str
    link: str
    shape: Shape
    local: np.ndarray


@dataclass
class Joint:
    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float


@dataclass
class Robot:
    root: str
    links: list
    joints: dict  # name -> Joint
    elements: dict  # link -> [Element]

    def child_joints(self, link):
        return [j for j in self.joints.values() if j.parent == link]

    def subtree(self, link):
        """`link` and every link below it."""
        out = [link]
        for j in self.child_joints(link):
            out += self.subtree(j.child)
        return out


def parse_origin(node):
    o = node.find("origin") if node is not None else None
    xyz = floats(o.get("xyz") if o is not None else None, (0, 0, 0))
    rpy = floats(o.get("rpy") if o is not None else None, (0, 0, 0))
    return pose(rpy_matrix(*rpy), xyz)


def resolve_mesh(filename, base_dir):
    """A URDF mesh path: file://, package://PKG/REST (looked for next to the URDF) or relative."""
    if filename.startswith("file://"):
        return Path(filename[len("file://"):])
    if filename.startswith("package://"):
        rest = Path(*Path(filename[len("package://"):]).parts[1:])
        for cand in (base_dir / rest, base_dir.parent / rest):
            if cand.exists():
                return cand
        return base_dir / rest
    return base_dir / filename


def parse_geometry(geom, base_dir):
    g = list(geom)[0]
    if g.tag == "box":
        return Shape("box", floats(g.get("size"), ()))
    if g.tag == "cylinder":
        return Shape("cylinder", [float(g.get("radius")), float(g.get("length"))])
    if g.tag == "sphere":
        return Shape("sphere", [float(g.get("radius"))])
    if g.tag == "mesh":
        return Shape("mesh", [], resolve_mesh(g.get("filename"), base_dir),
                     np.array(floats(g.get("scale"), (1, 1, 1))))
    raise ValueError(f"unsupported URDF geometry <{g.tag}>")


def parse_urdf(path):
    root = ET.parse(path).getroot()
    base_dir = Path(path).parent
    links = [l.get("name") for l in root.findall("link")]
    elements = {}
    for l in root.findall("link"):
        name = l.get("name")
        elements[name] = [Element(name, name, parse_geometry(c.find("geometry"), base_dir),
                                  parse_origin(c)) for c in l.findall("collision")]
    joints = {}
    for j in root.findall("joint"):
        axis = j.find("axis")
        axis = np.array(floats(axis.get("xyz") if axis is not None else None, (1, 0, 0)))
        limit = j.find("limit")
        lower = float(limit.get("lower", 0)) if limit is not None else -math.inf
        upper = float(limit.get("upper", 0)) if limit is not None else math.inf
        if j.get("type") == "continuous":
            lower, upper = -math.inf, math.inf
        joints[j.get("name")] = Joint(j.get("name"), j.get("type"), j.find("parent").get("link"),
                                      j.find("child").get("link"), parse_origin(j),
                                      axis / np.linalg.norm(axis), lower, upper)
    children = {j.child for j in joints.values()}
    roots = [l for l in links if l not in children]
    if len(roots) != 1:
        raise ValueError(f"{path}: expected one root link, found {roots}")
    return Robot(roots[0], links, joints, elements)


# ---------------------------------------------------------------------------------------------
# Forward kinematics


def joint_motion(joint, value):
    if joint.kind in ("revolute", "continuous"):
        return pose(axis_rotation(joint.axis, value), (0, 0, 0))
    if joint.kind == "prismatic":
        return pose(np.eye(3), joint.axis * value)
    return np.eye(4)  # fixed (floating and planar joints are held at their origin)


class Kinematics:
    """Link poses in the frame of `root_link` as functions of the planned joints."""

    def __init__(self, robot, planned, fixed_values, root_link):
        for name in planned:
            if robot.joints[name].kind not in ("revolute", "continuous", "prismatic"):
                raise ValueError(f"planned joint {name} is {robot.joints[name].kind}")
        self.robot, self.planned = robot, list(planned)
        self.fixed = {n: float(fixed_values.get(n, 0.0)) for n in robot.joints}
        self.order = self._joint_order()
        moving = set()
        for name in planned:
            moving.update(robot.subtree(robot.joints[name].child))
        self.moving_links = moving
        # Below the planned joints: (joint, its fixed transform, or None when it is planned).
        self.moving_joints = [(j, None if j.name in planned else
                               j.origin @ joint_motion(j, self.fixed[j.name]))
                              for j in self.order if j.child in moving]
        static = self._all_poses(self.fixed)
        if root_link in moving:
            raise ValueError(f"root_link {root_link} moves with the planned joints")
        rebase = np.linalg.inv(static[root_link])
        self.static = {link: rebase @ T for link, T in static.items()}

    def _joint_order(self):
        order, frontier = [], [self.robot.root]
        while frontier:
            link = frontier.pop(0)
            for j in self.robot.child_joints(link):
                order.append(j)
                frontier.append(j.child)
        return order

    def _all_poses(self, values):
        T = {self.robot.root: np.eye(4)}
        for j in self.order:
            T[j.child] = T[j.parent] @ j.origin @ joint_motion(j, values[j.name])
        return T

    def poses(self, q):
        values = dict(zip(self.planned, q))
        T = dict(self.static)
        for j, fixed in self.moving_joints:
            local = fixed if fixed is not None else j.origin @ joint_motion(j, values[j.name])
            T[j.child] = T[j.parent] @ local
        return T

    def limits(self):
        lo = np.array([self.robot.joints[n].lower for n in self.planned])
        hi = np.array([self.robot.joints[n].upper for n in self.planned])
        return lo, hi


# ---------------------------------------------------------------------------------------------
# Shapes


def load_mesh(path):
    """Vertices (n×3) and triangles (m×3) of an OBJ or STL (ASCII or binary) file."""
    data = Path(path).read_bytes()
    if path.suffix.lower() == ".obj":
        return parse_obj(data.decode(errors="replace"))
    if path.suffix.lower() == ".stl":
        return parse_stl(data)
    raise ValueError(f"{path}: only OBJ and STL meshes are read")


def parse_obj(text):
    verts, tris = [], []
    for line in text.splitlines():
        parts = line.split()
        if parts and parts[0] == "v":
            verts.append([float(v) for v in parts[1:4]])
        elif parts and parts[0] == "f":
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            tris += [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]
    return np.array(verts, float), np.array(tris, int).reshape(-1, 3)


def parse_stl(data):
    count = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    if len(data) == 84 + 50 * count:  # binary
        rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)),
                                                       ("a", "<u2")]), count=count)
        verts = rec["v"].reshape(-1, 3).astype(float)
    else:
        verts = np.array([[float(v) for v in line.split()[1:4]]
                          for line in data.decode(errors="replace").splitlines()
                          if line.strip().startswith("vertex")])
    return verts, np.arange(len(verts)).reshape(-1, 3)


def mesh_vertices(shape):
    verts, tris = load_mesh(shape.mesh)
    return verts * shape.scale, tris


def convex_hull(verts):
    from scipy.spatial import ConvexHull  # only needed for mesh shapes
    hull = ConvexHull(verts)
    used = np.unique(hull.simplices)
    remap = {int(old): new for new, old in enumerate(used)}
    faces = [[remap[int(i)] for i in tri] for tri in hull.simplices]
    return verts[used], faces


def fcl_geometry(shape, mesh_mode="hull"):
    if shape.kind == "box":
        return fcl.Box(*shape.size)
    if shape.kind == "cylinder":
        return fcl.Cylinder(shape.size[0], shape.size[1])
    if shape.kind == "sphere":
        return fcl.Sphere(shape.size[0])
    if shape.kind == "capsule":
        return fcl.Capsule(shape.size[0], shape.size[1])
    if shape.kind == "mesh":
        verts, tris = mesh_vertices(shape)
        if mesh_mode == "triangles":
            model = fcl.BVHModel()
            model.beginModel(len(verts), len(tris))
            model.addSubModel(verts, tris)
            model.endModel()
            return model
        hull, faces = convex_hull(verts)
        return fcl.Convex(hull, len(faces), [v for f in faces for v in [3] + f])
    raise ValueError(f"unsupported shape {shape.kind}")


def bounding_radius(shape):
    """Radius of a sphere about the shape's origin that contains the shape."""
    s = shape.size
    if shape.kind == "box":
        return 0.5 * math.sqrt(s[0] ** 2 + s[1] ** 2 + s[2] ** 2)
    if shape.kind == "cylinder":
        return math.hypot(s[0], 0.5 * s[1])
    if shape.kind == "sphere":
        return s[0]
    if shape.kind == "capsule":
        return s[0] + 0.5 * s[1]
    return float(np.linalg.norm(mesh_vertices(shape)[0], axis=1).max())


# ---------------------------------------------------------------------------------------------
# The export


def load_export(path, urdf=None):
    """The export with the optional keys filled in as the format says."""
    path = Path(path)
    ex = json.loads(path.read_text())
    if not (urdf or ex.get("urdf") or ex.get("robot")):
        raise SystemExit(f"{path}: no urdf nor robot in the file: pass --urdf")
    urdf = Path(urdf).resolve() if urdf else ex.get("urdf") or ROBOTS_DIR / f"{ex['robot']}.urdf"
    ex["urdf"] = path.parent / urdf  # an absolute path stays as it is
    robot = parse_urdf(ex["urdf"])
    ex.setdefault("root_link", robot.root)
    ex.setdefault("fixed_joints", {})
    ex.setdefault("self_pairs", [])
    ex.setdefault("attached", [])
    ex.setdefault("resolution_m", 0.01)
    if "moving_links" not in ex:
        first = robot.joints[ex["joints"][0]]
        ex["moving_links"] = robot.subtree(first.child)
    for thing in ex["objects"] + ex["attached"]:
        if thing.get("mesh"):
            thing["mesh"] = path.parent / thing["mesh"]
    return ex, robot


def export_shape(obj):
    shape = Shape(obj["shape"], list(obj.get("size", [])))
    if shape.kind == "mesh":
        shape.mesh = Path(obj["mesh"])
        extents = np.ptp(mesh_vertices(shape)[0], axis=0)
        if shape.size and not np.allclose(extents, shape.size, rtol=1e-3, atol=1e-6):
            print(f"warning: {obj['id']}: mesh extents {extents.tolist()} differ from size "
                  f"{shape.size}; the mesh file is used as it is", file=sys.stderr)
    return shape


def export_pose(obj):
    return pose(quat_matrix(obj.get("quaternion", [0, 0, 0, 1])), obj.get("position", [0, 0, 0]))


# ---------------------------------------------------------------------------------------------
# Motion resolution


def joint_reach(robot, kin, attached):
    """For each planned joint, an upper bound on how far a point of the robot below it moves
    per unit of that joint (m/rad, or 1 m/m for a prismatic joint), whatever the other joints.

    A revolute joint moves a point p at |axis × (p - o)| <= |p - o| per radian, o on the axis
    (the child link's origin). |p - o| is bounded by summing, down the tree, the norms of the
    joint origins' offsets (plus a prismatic joint's largest travel) and, at the end, the
    offset of a collision shape's origin plus the shape's bounding radius."""
    extra = {}
    for a in attached:
        r = float(np.linalg.norm(a.get("position", [0, 0, 0]))) + bounding_radius(export_shape(a))
        extra[a["link"]] = max(extra.get(a["link"], 0.0), r)

    def radius_below(link):
        r = extra.get(link, 0.0)
        for e in robot.elements[link]:
            r = max(r, float(np.linalg.norm(e.local[:3, 3])) + bounding_radius(e.shape))
        for j in robot.child_joints(link):
            travel = 0.0
            if j.kind == "prismatic":
                travel = (max(abs(j.lower), abs(j.upper)) if j.name in kin.planned
                          else abs(kin.fixed[j.name]))
            r = max(r, float(np.linalg.norm(j.origin[:3, 3])) + travel + radius_below(j.child))
        return r

    return np.array([1.0 if robot.joints[n].kind == "prismatic"
                     else radius_below(robot.joints[n].child) for n in kin.planned])


def point_motion_bound(reach, a, b):
    """Upper bound on the distance any robot point travels along the straight edge a -> b."""
    return float(np.sum(reach * np.abs(np.asarray(b) - np.asarray(a))))


# ---------------------------------------------------------------------------------------------
# Collision checking


class Scene:
    """FCL objects for the checked robot shapes, attached objects and the world objects."""

    def __init__(self, ex, robot, kin, object_mesh="triangles"):
        self.kin = kin
        self.request = fcl.CollisionRequest()
        self.checks = 0  # states checked so far
        pair_names = {n for pair in ex["self_pairs"] for n in pair}
        elements = []
        for link in dict.fromkeys(list(ex["moving_links"]) + sorted(pair_names)):
            elements += robot.elements.get(link, [])
        elements += [Element(a["id"], a["link"], export_shape(a), export_pose(a))
                     for a in ex["attached"]]
        self.elements = elements
        self.robot_objs = [fcl.CollisionObject(fcl_geometry(e.shape)) for e in elements]
        self.robot_radius = np.array([bounding_radius(e.shape) for e in elements])
        self.moving = [i for i, e in enumerate(elements) if e.link in kin.moving_links]
        checked = set(ex["moving_links"]) | {a["id"] for a in ex["attached"]}
        self.vs_objects = np.array([i for i, e in enumerate(elements) if e.name in checked], int)
        for name in (checked | pair_names) - {e.name for e in elements}:
            print(f"warning: {name} has no collision shape; it is not checked", file=sys.stderr)
        self.pairs = [(i, k) for a, b in ex["self_pairs"]
                      for i, e in enumerate(elements) if e.name == a
                      for k, f in enumerate(elements) if f.name == b]
        self.obj_ids = [o["id"] for o in ex["objects"]]
        shapes = [export_shape(o) for o in ex["objects"]]
        poses = [export_pose(o) for o in ex["objects"]]
        self.obj_objs = [fcl.CollisionObject(fcl_geometry(s, object_mesh),
                                             fcl.Transform(T[:3, :3], T[:3, 3]))
                         for s, T in zip(shapes, poses)]
        self.obj_center = np.array([T[:3, 3] for T in poses]).reshape(-1, 3)
        self.obj_radius = np.array([bounding_radius(s) for s in shapes])
        self.centers = np.zeros((len(elements), 3))
        self._place(range(len(elements)), kin.static)

    def _place(self, indices, link_poses):
        for i in indices:
            T = link_poses[self.elements[i].link] @ self.elements[i].local
            self.robot_objs[i].setTransform(fcl.Transform(T[:3, :3], T[:3, 3]))
            self.centers[i] = T[:3, 3]

    def collisions(self, q, first_only=True):
        """(a, b) name pairs in contact at joint values q (at most one when first_only)."""
        self.checks += 1
        self._place(self.moving, self.kin.poses(q))
        found = []
        if len(self.obj_objs):
            idx = self.vs_objects
            gap = np.linalg.norm(self.centers[idx, None] - self.obj_center[None], axis=2)
            near = gap <= self.robot_radius[idx, None] + self.obj_radius[None]
            for a, b in np.argwhere(near):
                if fcl.collide(self.robot_objs[idx[a]], self.obj_objs[b], self.request):
                    found.append((self.elements[idx[a]].name, self.obj_ids[b]))
                    if first_only:
                        return found
        for i, k in self.pairs:
            gap = np.linalg.norm(self.centers[i] - self.centers[k])
            if gap <= self.robot_radius[i] + self.robot_radius[k] and \
                    fcl.collide(self.robot_objs[i], self.robot_objs[k], self.request):
                found.append((self.elements[i].name, self.elements[k].name))
                if first_only:
                    return found
        return found

    def is_valid(self, q):
        return not self.collisions(q, first_only=True)


def setup(path, urdf=None, object_mesh="triangles"):
    ex, robot = load_export(path, urdf)
    kin = Kinematics(robot, ex["joints"], ex["fixed_joints"], ex["root_link"])
    scene = Scene(ex, robot, kin, object_mesh)
    reach = joint_reach(robot, kin, ex["attached"])
    return ex, kin, scene, reach


# ---------------------------------------------------------------------------------------------
# check


def check_path(i, problem, kin, scene, reach, step, report):
    path = np.asarray(problem["path"], float)
    lo, hi = kin.limits()
    errors = report["errors"]
    for end, state in (("start", path[0]), ("goal", path[-1])):
        if np.max(np.abs(state - np.asarray(problem[end], float))) > END_TOLERANCE:
            errors.append({"problem": i, "error": f"the path's {end} is not the problem's {end}"})
    outside = np.where((path < lo - LIMIT_TOLERANCE) | (path > hi + LIMIT_TOLERANCE))
    for s, j in sorted(set(zip(*outside))):
        errors.append({"problem": i, "error": f"state {s}: {kin.planned[j]} = {path[s, j]} "
                                              f"outside [{lo[j]}, {hi[j]}]"})
    report["edges"] += len(path) - 1
    edges = list(zip(path[:-1], path[1:])) or [(path[0], path[0])]  # one state: check it
    for k, (a, b) in enumerate(edges):
        n = max(1, math.ceil(point_motion_bound(reach, a, b) / step))
        seen = set()
        for s in range(0 if k == 0 else 1, n + 1):
            for x, y in scene.collisions(a + (b - a) * (s / n), first_only=False):
                if (x, y) not in seen:
                    seen.add((x, y))
                    report["collisions"].append(
                        {"problem": i, "edge": k, "a": x, "b": y, "t": round(s / n, 6)})
            report["states_checked"] += 1


def cmd_check(args):
    ex, kin, scene, reach = setup(args.export, args.urdf, args.object_mesh)
    report = {"paths": 0, "edges": 0, "states_checked": 0, "collisions": [], "errors": [],
              "skipped": 0, "step_m": args.step, "joint_reach_m": reach.round(6).tolist()}
    for i, problem in enumerate(ex["problems"]):
        if not problem.get("path"):
            report["skipped"] += 1
            continue
        report["paths"] += 1
        check_path(i, problem, kin, scene, reach, args.step, report)
    report["ok"] = not report["collisions"] and not report["errors"]
    print(json.dumps(report))
    return 0 if report["ok"] else 1


# ---------------------------------------------------------------------------------------------
# ompl


def percentile(values, p):
    """Nearest-rank percentile: the smallest value with at least p% of the values at or below."""
    ordered = sorted(values)
    return ordered[max(0, math.ceil(p / 100 * len(ordered)) - 1)]


def path_length(states):
    return float(np.sum(np.linalg.norm(np.diff(states, axis=0), axis=1))) if len(states) > 1 else 0.0


def ompl_version():
    from importlib.metadata import version
    return version("ompl")


def make_setup(kin, scene, step, planner_range=0.0):
    """A SimpleSetup with RRTConnect over the planned joints' box; edges checked every `step`;
    RRTConnect's range `planner_range` (rad; 0: OMPL's default, a fifth of the extent)."""
    from ompl import base as ob, geometric as og
    lo, hi = kin.limits()
    lo, hi = np.where(np.isfinite(lo), lo, -math.pi), np.where(np.isfinite(hi), hi, math.pi)
    space = ob.RealVectorStateSpace(len(lo))
    bounds = ob.RealVectorBounds(len(lo))
    for j, (l, h) in enumerate(zip(lo, hi)):
        bounds.setLow(j, float(l))
        bounds.setHigh(j, float(h))
    space.setBounds(bounds)
    # OMPL checks an edge every longestValidSegment = fraction * maximum extent (Euclidean).
    space.setLongestValidSegmentFraction(step / space.getMaximumExtent())
    ss = og.SimpleSetup(space)
    n = len(lo)
    ss.setStateValidityChecker(lambda s: scene.is_valid([s[j] for j in range(n)]))
    planner = og.RRTConnect(ss.getSpaceInformation())
    if planner_range > 0:
        planner.setRange(planner_range)
    ss.setPlanner(planner)
    ss.setup()
    return ss, space


def ompl_state(space, values):
    s = space.allocState()
    for j, v in enumerate(values):
        s[j] = float(v)
    return s


def solve_one(ss, space, scene, problem, time_limit, simplify):
    ss.clear()
    ss.setStartAndGoalStates(ompl_state(space, problem["start"]), ompl_state(space, problem["goal"]))
    checks = scene.checks
    t0 = time.perf_counter()
    ss.solve(time_limit)
    success = ss.haveExactSolutionPath()
    if success and simplify:
        ss.simplifySolution()
    elapsed = (time.perf_counter() - t0) * 1e3
    result = {"success": success, "time_ms": round(elapsed, 3), "path_length_rad": None,
              "states_checked": scene.checks - checks}
    if not success:
        return result, None
    path = ss.getSolutionPath()
    n = space.getDimension()
    states = np.array([[path.getState(k)[j] for j in range(n)] for k in range(path.getStateCount())])
    result["path_length_rad"] = round(path_length(states), 6)
    return result, states


def cmd_ompl(args):
    from ompl import util as ou
    ou.RNG.setSeed(args.seed)  # before any OMPL sampler exists
    ou.setLogLevel(ou.LOG_WARN)
    ex, kin, scene, reach = setup(args.export, args.urdf, args.object_mesh)
    # Any robot point moves at most sum_i reach_i |dq_i| <= |reach|_2 |dq|_2 (Cauchy-Schwarz).
    step = ex["resolution_m"] / float(np.linalg.norm(reach))
    ss, space = make_setup(kin, scene, step, args.range)
    per_problem, paths = [], []
    for problem in ex["problems"]:
        result, states = solve_one(ss, space, scene, problem, args.time_limit, args.simplify)
        per_problem.append(result)
        paths.append(states)
    times = [r["time_ms"] for r in per_problem]
    lengths = [r["path_length_rad"] for r in per_problem if r["success"]]
    out = {
        "planner": "ompl-RRTConnect", "ompl_version": ompl_version(),
        "problems": len(per_problem),
        "success_rate": sum(r["success"] for r in per_problem) / max(1, len(per_problem)),
        "time_ms": {"median": float(np.median(times)) if times else None,
                    "p95": percentile(times, 95) if times else None,
                    "max": max(times) if times else None},
        "path_length_rad": {"median": float(np.median(lengths)) if lengths else None},
        "simplify": args.simplify, "time_limit_s": args.time_limit, "seed": args.seed,
        "range_rad": ss.getPlanner().getRange(),
        "motion_check": {"resolution_m": ex["resolution_m"], "step_rad": step,
                         "ompl_segment_rad": space.getLongestValidSegmentLength(),
                         "joint_reach_m": reach.round(6).tolist()},
        "per_problem": per_problem,
    }
    if args.paths_out:
        write_paths(args.export, args.paths_out, per_problem, paths)
    print(json.dumps(out))
    return 0


def write_paths(export_path, out_path, per_problem, paths):
    """The export as read, with OMPL's results in place of Ferrobot's (urdf made absolute)."""
    ex = json.loads(Path(export_path).read_text())
    base = Path(export_path).resolve().parent
    for key in ("urdf",):
        if ex.get(key):
            ex[key] = str(base / ex[key])
    for thing in ex["objects"] + ex.get("attached", []):
        if thing.get("mesh"):
            thing["mesh"] = str(base / thing["mesh"])
    for problem, result, states in zip(ex["problems"], per_problem, paths):
        problem.update(success=result["success"], time_ms=result["time_ms"],
                       path=states.tolist() if states is not None else [])
    Path(out_path).write_text(json.dumps(ex, indent=1))


# ---------------------------------------------------------------------------------------------


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name in ("ompl", "check"):
        p = sub.add_parser(name)
        p.add_argument("export")
        p.add_argument("--urdf", help="URDF to use instead of the export's")
        p.add_argument("--object-mesh", choices=("triangles", "hull"), default="triangles",
                       help="mesh objects as triangle meshes (default) or convex hulls")
    ompl_p, check_p = sub.choices["ompl"], sub.choices["check"]
    ompl_p.add_argument("--time-limit", type=float, default=1.0, help="seconds per problem")
    ompl_p.add_argument("--simplify", action="store_true")
    ompl_p.add_argument("--seed", type=int, default=1)
    ompl_p.add_argument("--range", type=float, default=0.0,
                        help="RRTConnect's range, rad (0: OMPL's default, a fifth of the extent)")
    ompl_p.add_argument("--paths-out", help="write the export with OMPL's paths here")
    check_p.add_argument("--step", type=float, default=0.001,
                         help="largest link-point motion between checked states (m)")
    args = parser.parse_args(argv)
    return cmd_ompl(args) if args.command == "ompl" else cmd_check(args)


if __name__ == "__main__":
    sys.exit(main())
