#!/usr/bin/env python3
"""Peer of Ferrobot's DBSCAN (ferrobot_perception::cluster): scikit-learn's on the same cloud.

  dbscan_peer.py CLOUD.ply --eps 0.02 --min-samples 15 [--eps E2 --min-samples M2 ...] [--repeat 1]

reads a PLY cloud (binary little-endian or ASCII; vertex properties of any scalar type, x y z
used, as ferrobot's `write_ply` writes them: float x y z, uchar red green blue), converts the
points to float64 (as Ferrobot's reader does), runs
`sklearn.cluster.DBSCAN(eps=EPS, min_samples=M).fit(X)` (metric euclidean, every other
parameter at its default) REPEAT times on one thread for each (eps, min_samples) pair, and
prints one JSON object for one pair:

  {"labels": [...], "core": [0/1, ...], "seconds": [fit time of each repeat],
   "algorithm": the neighbour search scikit-learn chose ("kd_tree" or "brute" ...),
   "sklearn": its version, "points": N, "eps": E, "min_samples": M}

or {"runs": [one such object per pair, in order]} for several (one Python start-up, which
takes longer than most fits).

  dbscan_peer.py --batch CASES.json

runs several clouds in one start-up: CASES.json is a list of {"cloud": PATH, "eps": [E, ...],
"min_samples": [M, ...], "repeat": R (optional)}, and the output is {"batch": [{"runs": [...]}
for each case, in order]}.

The fit times cover `fit` only (the tree, the neighbourhoods and the labelling), not reading
the file. Threads: OMP/OpenBLAS/MKL limited to one before numpy is imported, and
threadpoolctl's limit around the fits; DBSCAN's own n_jobs stays at its default (one).

Run with the venv that `scripts/python-env.sh cluster` makes:
  target/py-venv/bin/python host/perception/peer/dbscan_peer.py cloud.ply --eps 0.02 --min-samples 15
"""

import argparse
import json
import os
import sys
import time

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import numpy as np  # noqa: E402
import sklearn  # noqa: E402
from sklearn.cluster import DBSCAN  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply(path):
    """The cloud's points as an N x 3 float64 array."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply") or end < 0:
        sys.exit(f"{path}: not a PLY file")
    header = data[:end].decode("ascii").splitlines()
    body = data[end + len(b"end_header\n"):]
    fmt, count, props, in_vertex = None, None, [], False
    for line in header:
        words = line.split()
        if not words:
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
        elif words[0] == "property" and in_vertex:
            if words[1] == "list":
                sys.exit(f"{path}: list properties on vertices are not supported")
            props.append((words[2], PLY_TYPES[words[1]]))
    if count is None:
        sys.exit(f"{path}: no vertex element")
    names = [n for n, _ in props]
    if fmt == "binary_little_endian":
        dtype = np.dtype([(n, "<" + t) for n, t in props])
        v = np.frombuffer(body, dtype=dtype, count=count)
        cols = [v[c].astype(np.float64) for c in ("x", "y", "z")]
    elif fmt == "ascii":
        rows = np.loadtxt(body.decode("ascii").splitlines()[:count], ndmin=2)
        cols = [rows[:, names.index(c)].astype(np.float64) for c in ("x", "y", "z")]
    else:
        sys.exit(f"{path}: format {fmt} is not supported")
    return np.ascontiguousarray(np.stack(cols, axis=1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cloud", nargs="?")
    ap.add_argument("--eps", type=float, action="append")
    ap.add_argument("--min-samples", type=int, action="append")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--batch", help="a JSON list of cases, each with its own cloud")
    a = ap.parse_args()
    if a.batch is not None:
        if a.cloud is not None or a.eps or a.min_samples:
            sys.exit("--batch takes its clouds and parameters from its file alone")
        with open(a.batch) as f:
            cases = json.load(f)
        batch = [
            {"runs": runs(case["cloud"], case["eps"], case["min_samples"], case.get("repeat", 1))}
            for case in cases
        ]
        print(json.dumps({"batch": batch}))
        return
    if a.cloud is None or not a.eps or not a.min_samples:
        sys.exit("give a cloud and at least one --eps and --min-samples (or --batch)")
    out = runs(a.cloud, a.eps, a.min_samples, a.repeat)
    print(json.dumps(out[0] if len(out) == 1 else {"runs": out}))


def runs(cloud, eps, min_samples, repeat):
    """One run for each (eps, min_samples) pair on the cloud in the PLY file `cloud`."""
    if len(eps) != len(min_samples):
        sys.exit("give one min_samples per eps")
    x = read_ply(cloud)
    return [run(x, e, m, repeat) for e, m in zip(eps, min_samples)]


def run(x, eps, min_samples, repeat):
    seconds, db = [], None
    with threadpool_limits(limits=1):
        for _ in range(max(1, repeat)):
            t = time.perf_counter()
            db = DBSCAN(eps=eps, min_samples=min_samples).fit(x)
            seconds.append(time.perf_counter() - t)
    core = np.zeros(len(x), dtype=np.int64)
    core[db.core_sample_indices_] = 1
    # The neighbour search `algorithm="auto"` chose: what a NearestNeighbors with DBSCAN's
    # settings (radius eps, leaf_size 30, euclidean) picks for these points.
    from sklearn.neighbors import NearestNeighbors

    nn = NearestNeighbors(radius=eps, algorithm="auto", leaf_size=30, metric="euclidean")
    return {
        "algorithm": nn.fit(x)._fit_method,
        "core": core.tolist(),
        "eps": eps,
        "labels": db.labels_.astype(np.int64).tolist(),
        "min_samples": min_samples,
        "points": int(len(x)),
        "seconds": seconds,
        "sklearn": sklearn.__version__,
    }


if __name__ == "__main__":
    main()
