#!/usr/bin/env bash
# Creates target/py-venv with the Python packages the conformance tests need (ROBOTIS'
# official Dynamixel SDK); with `bench`, also those the benchmarks compare against (PyBullet,
# benches/benches/requirements.txt); with `plan`, also those of the planning benchmark's peer
# (OMPL and FCL, host/planning/peer/requirements.txt); with `cluster`, also the clustering
# peer's (scikit-learn, host/perception/peer/requirements.txt); with `slam`, also the
# renderer of SLAM's independent test sequences (PyBullet, host/slam/peer/requirements.txt);
# with `python`, also what the Python package's tests use (pytest, yourdfpy,
# host/python/requirements-test.txt).
# Idempotent: does nothing when
# they are already there.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/py-venv
install() { # REQUIREMENTS STAMP MODULE
    if ! cmp -s "$1" "$venv/$2" 2>/dev/null; then
        "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$1"
        cp "$1" "$venv/$2"
    fi
    "$venv/bin/python" -c "import $3"
}
if [ ! -x "$venv/bin/python" ]; then
    mkdir -p target
    if ! python3 -m venv "$venv" 2>/dev/null; then
        echo "python3 -m venv failed; installing python3-venv" >&2
        apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
        python3 -m venv "$venv"
    fi
fi
install sim-stubs/tests/conformance/requirements.txt .installed-requirements dynamixel_sdk
case "${1:-}" in
    "") ;;
    bench) install benches/benches/requirements.txt .installed-bench-requirements pybullet ;;
    plan) install host/planning/peer/requirements.txt .installed-plan-requirements "ompl.geometric, fcl, scipy.spatial" ;;
    cluster) install host/perception/peer/requirements.txt .installed-cluster-requirements "sklearn.cluster" ;;
    slam) install host/slam/peer/requirements.txt .installed-slam-requirements "pybullet, numpy" ;;
    python) install host/python/requirements-test.txt .installed-python-requirements "numpy, pytest, yourdfpy, absl, ipykernel, nbclient" ;;
    *) echo "usage: $0 [bench|plan|cluster|slam|python]" >&2; exit 2 ;;
esac
