#!/usr/bin/env python3
"""Peer for `ferrobot bench plan`: VAMP (Thomason, Kingston & Kavraki, ICRA 2024) on its own
MotionBenchMaker problems for the Panda, and ours on the same problems, in one run.

  vamp_peer.py PANDA_DIR OUT_DIR [--ferrobot target/release/ferrobot] [--sets table_pick,box]
               [--engines auto,baseline] [--repeats 3]
      PANDA_DIR is VAMP's `resources/panda` (from the `vamp-planner` source distribution) after
      VAMP's `resources/problem_tar_to_pkl_json.py --robot panda` made its `problems.pkl`.
      Writes into OUT_DIR:
        - panda.toml and panda_spherized.urdf: the Panda as Ferrobot's description holds it,
          with VAMP's own collision model (59 spheres, the fingers fixed as VAMP has them) and
          the collision matrix of VAMP's SRDF (MoveIt's disabled pairs);
        - problems/SET-NNN.json: each problem as a problems file (`bench plan --problems-file`):
          its objects (boxes, cylinders, spheres, in the Panda's base frame) and its start and
          first goal;
        - vamp.json and ferrobot-ENGINE.json: per problem, success, time and path length.
      Then prints a table by set for each of --engines (auto: the checker's choice):
      success, median and p95 time, median path length (rad, joint-space Euclidean) for both,
      and the ratio of the medians.

Times: VAMP's are its own clock (`results_to_dict`'s total_time: RRT-Connect and
simplification, without the Python bindings' overhead, which the wall clock beside it
shows); ours are `bench plan`'s (search and shortcutting, per problem, without loading the
robot). Both planners run with their defaults, one problem at a time, on one core: VAMP then
each engine of ours on each problem before the next, so that a machine's changing load falls
on both; with --repeats N each plans each problem N times (the same path) and its median time
is kept. VAMP checks edges at a fixed joint-space resolution; ours are proven free between
the states checked (a different guarantee, paid for in time).

Run with a Python that has VAMP (`pip install vamp-planner`, which builds it from source:
cmake, a C++17 compiler and Eigen 3) and numpy; see BENCHMARKS.md for the command used.
"""

import argparse
import json
import pickle
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

JOINTS = [f"panda_joint{i}" for i in range(1, 8)]
# The Panda's velocity limits (rad/s, franka_description), for the description's [[joint]]s.
VELOCITY = [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]
# MoveIt's reasons (SRDF) as the description's [collision] table names them.
REASONS = {"Adjacent": "adjacent", "Never": "never", "Default": "always"}


def write_robot(panda: Path, out: Path, planning_range: float) -> None:
    """The Panda's configuration and URDF in `out`, its arm's extension step
    `planning_range` (rad; 0: none, `bench plan`'s default of a fifth of the joint box's
    diagonal)."""
    shutil.copy(panda / "panda_spherized.urdf", out / "panda_spherized.urdf")
    srdf = (panda / "panda.srdf").read_text()
    pairs = re.findall(
        r'<disable_collisions link1="([^"]+)" link2="([^"]+)" reason="([^"]+)"', srdf
    )
    lines = [
        "# The Panda of VAMP's resources (franka_description, VAMP's spherized collision model).",
        'name = "panda"',
        'urdf = "panda_spherized.urdf"',
        'board_profile = "sawyer"',
        "",
        "[arm]",
        "joints = [" + ", ".join(f'"{j}"' for j in JOINTS) + "]",
        'base_frame = "panda_link0"',
        'ee_frame = "panda_hand"',
        "home = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]",
        'ik = "numerical"',
        "ik_position_tolerance = 1e-5",
        "ik_orientation_tolerance = 1e-5",
        "joint_tolerance = 0.01",
        "timeout = 20.0",
    ]
    if planning_range > 0:
        lines.append(f"planning_range = {planning_range}")
    for i, (j, v) in enumerate(zip(JOINTS, VELOCITY)):
        lines += [
            "",
            "[[joint]]",
            f'name = "{j}"',
            'kind = "arm"',
            f'servo = {{ id = {i + 1}, model = "xm430-w350" }}',
            f"limits = {{ velocity = {v} }}",
            "effort_limit = 3.5",
        ]
    lines += ["", "[collision]", "disabled = ["]
    lines += [f'    ["{a}", "{b}", "{REASONS.get(r, "never")}"],' for a, b, r in pairs]
    lines += ["]", ""]
    (out / "panda.toml").write_text("\n".join(lines))


def objects_of(d: dict) -> list:
    """A problem's obstacles as `bench plan` objects (unique ids, full sizes)."""
    objs = []
    for o in d["box"]:
        size = [2 * h for h in o["half_extents"]]
        objs.append(("box", o, size, o["orientation_quat_xyzw"]))
    for o in d["cylinder"]:
        objs.append(("cylinder", o, [o["radius"], o["length"]], o["orientation_quat_xyzw"]))
    for o in d["sphere"]:
        objs.append(("sphere", o, [o["radius"]], [0.0, 0.0, 0.0, 1.0]))
    out, seen = [], {}
    for shape, o, size, quat in objs:
        name = o.get("name", shape)
        seen[name] = seen.get(name, 0) + 1
        out.append(
            {
                "id": name if seen[name] == 1 else f"{name}_{seen[name]}",
                "shape": shape,
                "size": [float(s) for s in size],
                "position": [float(x) for x in o["position"]],
                "quaternion": [float(x) for x in quat],
            }
        )
    return out


def vamp_planner(repeats: int = 1):
    """A function planning one (name, problem dict) with VAMP's RRT-Connect and
    simplification, defaults, `repeats` times (the same path: its sampler is reset): the row
    with its median time."""
    import vamp

    (module, planner, plan_settings, simp_settings) = vamp.configure_robot_and_planner_with_kwargs(
        "panda", "rrtc"
    )
    sampler = module.halton()

    def plan(name: str, d: dict) -> dict:
        env = vamp.problem_dict_to_vamp(d)
        runs = []
        for _ in range(repeats):
            sampler.reset()
            t0 = time.perf_counter()
            result = planner(d["start"], d["goals"], env, plan_settings, sampler)
            if not result.solved:
                break
            simple = module.simplify(result.path, env, simp_settings, sampler)
            wall = time.perf_counter() - t0
            runs.append((vamp.results_to_dict(result, simple), wall))
        row = {"name": name, "success": len(runs) == repeats}
        if row["success"]:
            r, _ = runs[0]
            row.update(
                time_ms=statistics.median(r["total_time"].total_seconds() * 1e3 for r, _ in runs),
                wall_ms=statistics.median(w for _, w in runs) * 1e3,
                # Its cost: the joint-space Euclidean length, as ours.
                path_rad=float(r["simplified_path_cost"]),
            )
        return row

    return plan


def ours_planned(
    ferrobot: str, out: Path, name: str, engine: str, extra: list, repeats: int = 1
) -> dict:
    """`ferrobot bench plan` on problem `name`'s file, one process per run, its edges proven
    by `engine` (`bench plan --engine`), with `extra` arguments, `repeats` times (the same
    seed, the same path): the row with its median time."""
    row, times = None, []
    for _ in range(repeats):
        row = plan_ours(ferrobot, out, name, engine, extra)
        if not row["success"]:
            break
        times.append(row["time_ms"])
    if row["success"]:
        row["time_ms"] = statistics.median(times)
    return row


def plan_ours(ferrobot: str, out: Path, name: str, engine: str, extra: list) -> dict:
    """One run of `ferrobot bench plan` on problem `name`."""
    res = subprocess.run(
        [
            ferrobot,
            "bench",
            "plan",
            "--config",
            str(out / "panda.toml"),
            "--problems-file",
            str(out / "problems" / f"{name}.json"),
            "--json",
            "--engine",
            engine,
            *extra,
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    d = json.loads(res.stdout)
    ok = d.get("success_rate") == 1.0
    row = {"name": name, "success": ok}
    if ok:
        row.update(time_ms=d["time_ms"]["median"], path_rad=d["path_length_rad"]["median"])
    else:
        row["error"] = d.get("error", res.stderr.strip()[-300:])
    return row


def summary(rows: list) -> dict:
    ok = [r for r in rows if r["success"]]
    t = sorted(r["time_ms"] for r in ok)
    return {
        "problems": len(rows),
        "success": len(ok) / max(len(rows), 1),
        "median_ms": statistics.median(t) if t else float("nan"),
        "p95_ms": t[min(len(t) - 1, int(0.95 * len(t)))] if t else float("nan"),
        "path_rad": statistics.median(r["path_rad"] for r in ok) if ok else float("nan"),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("panda_dir", type=Path)
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--ferrobot", default="target/release/ferrobot")
    ap.add_argument("--sets", default="", help="comma-separated MotionBenchMaker sets (all)")
    ap.add_argument(
        "--planning-range",
        type=float,
        default=1.0,
        help="the Panda's extension step for ours, rad (1.0: VAMP's own default; 0: none)",
    )
    ap.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="plan each problem this many times, both planners, and keep its median time "
        "(the same path each time: both are seeded; repeats steady a busy machine's times)",
    )
    ap.add_argument("--shortcuts", type=int, help="ours: `bench plan --shortcuts` (its default)")
    ap.add_argument("--smoothing", type=int, help="ours: `bench plan --smoothing` (its default)")
    ap.add_argument(
        "--engines",
        default="auto",
        help="comma-separated `bench plan --engine`s to run ours with, one table each (auto)",
    )
    args = ap.parse_args()
    if args.repeats < 1:
        ap.error(f"--repeats {args.repeats}: at least 1")
    with open(args.panda_dir / "problems.pkl", "rb") as f:
        data = pickle.load(f)["problems"]
    sets = [s for s in args.sets.split(",") if s] or list(data)
    out = args.out_dir
    (out / "problems").mkdir(parents=True, exist_ok=True)
    write_robot(args.panda_dir, out, args.planning_range)
    problems = []
    for s in sets:
        for i, d in enumerate(data[s]):
            if not d["valid"]:
                continue
            name = f"{s}-{i:03d}"
            goal = [float(x) for x in d["goals"][0]]
            file = {
                "joints": JOINTS,
                "objects": objects_of(d),
                "problems": [{"start": [float(x) for x in d["start"]], "goal": goal}],
            }
            (out / "problems" / f"{name}.json").write_text(json.dumps(file))
            problems.append((name, dict(d, goals=[goal])))
    engines = [e for e in args.engines.split(",") if e]
    extra = [] if args.smoothing is None else ["--smoothing", str(args.smoothing)]
    extra += [] if args.shortcuts is None else ["--shortcuts", str(args.shortcuts)]
    # One problem at a time, VAMP then each engine of ours: every planner meets the machine
    # as it is at that moment (another process's load shifts both, not one).
    vamp_one = vamp_planner(args.repeats)
    vamp_rows, ours = [], {e: [] for e in engines}
    for name, d in problems:
        vamp_rows.append(vamp_one(name, d))
        for e in engines:
            ours[e].append(ours_planned(args.ferrobot, out, name, e, extra, args.repeats))
    (out / "vamp.json").write_text(json.dumps(vamp_rows))
    for engine in engines:
        ours_rows = ours[engine]
        (out / f"ferrobot-{engine}.json").write_text(json.dumps(ours_rows))
        print(f"\nours with --engine {engine}:\n")
        print("| set | VAMP success | VAMP median ms | VAMP p95 ms | VAMP path rad | ours success "
              "| ours median ms | ours p95 ms | ours path rad | ours / VAMP |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for s in sets + ["all"]:
            pick = (lambda r: True) if s == "all" else (lambda r, s=s: r["name"].rsplit("-", 1)[0] == s)
            v = summary([r for r in vamp_rows if pick(r)])
            o = summary([r for r in ours_rows if pick(r)])
            print(
                f"| {s} | {v['success']:.0%} | {v['median_ms']:.3f} | {v['p95_ms']:.2f} | "
                f"{v['path_rad']:.2f} | {o['success']:.0%} | {o['median_ms']:.3f} | "
                f"{o['p95_ms']:.2f} | {o['path_rad']:.2f} | {o['median_ms'] / v['median_ms']:.2f}× |"
            )
    walls = [r["wall_ms"] for r in vamp_rows if r["success"]]
    if walls:
        print(f"VAMP's wall clock through its Python bindings: median {statistics.median(walls):.3f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
