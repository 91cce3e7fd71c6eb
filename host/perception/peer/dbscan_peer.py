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
    ap.add_argument("cloud")
    ap.add_argument("--eps", type=float, action="append", required=True)
    ap.add_argument("--min-samples", type=int, action="append", required=True)
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    if len(a.eps) != len(a.min_samples):
        sys.exit("give one --min-samples per --eps")
    x = read_ply(a.cloud)
    runs = [run(x, eps, m, a.repeat) for eps, m in zip(a.eps, a.min_samples)]
    print(json.dumps(runs[0] if len(runs) == 1 else {"runs": runs}))


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
