#!/usr/bin/env bash
# Creates target/py-venv with the Python packages the conformance tests need (ROBOTIS'
# official Dynamixel SDK); with `bench`, also those the benchmarks compare against (PyBullet,
# benches/benches/requirements.txt); with `plan`, also those of the planning benchmark's peer
# (OMPL and FCL, host/planning/peer/requirements.txt); with `cluster`, also the clustering
# peer's (scikit-learn, host/perception/peer/requirements.txt); with `slam`, also the
# renderer of SLAM's independent test sequences (PyBullet, host/slam/peer/requirements.txt);
# with `python`, also what the Python package's tests use (pytest, yourdfpy,
# host/python/requirements-test.txt); with `realsense`, also Intel's librealsense for the
# RealSense server (pyrealsense2, host/peers/realsense/requirements.txt): where PyPI has no
# wheel of it for this platform, that is written to target/py-venv/.no-wheel-pyrealsense2 (the
# one reason its test may skip) and the step succeeds; with `record`, the independent readers
# of our recordings (Foxglove's mcap and rosbags) and of our LeRobot exports (pyarrow, pandas),
# host/record/peer/requirements.txt; with `zenoh`, the zenoh bridge's ROS 2 peer (eclipse-zenoh at
# rmw_zenoh Jazzy's version, rosbags), host/bridge/peer/requirements.txt; with `view`, the live
# view's viewer (websockets, rosbags), host/view/peer/requirements.txt.
# Idempotent: does nothing when
# they are already there.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/py-venv
install() { # REQUIREMENTS STAMP MODULE
    if ! cmp -s "$1" "$venv/$2" 2>/dev/null; then
        "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$1" || return 1
        cp "$1" "$venv/$2" || return 1
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
# install_wheel REQUIREMENTS STAMP MODULE PACKAGE: `install`, for a package whose wheels exist for
# some platforms only: when pip, having reached the index, finds no wheel of PACKAGE in any
# version for this platform ("from versions: none"), the note .no-wheel-PACKAGE says so instead
# of a failure; any other failure (the network, a pin that does not exist) fails.
install_wheel() {
    local note="$venv/.no-wheel-$4" log
    rm -f "$note"
    if log=$(install "$1" "$2" "$3" 2>&1); then
        [ -z "$log" ] || echo "$log"
        return 0
    fi
    local pin probe=0
    pin=$(grep -E "^$4==" "$1")
    log=$("$venv/bin/pip" download --disable-pip-version-check --no-deps \
        --only-binary=:all: -d "$venv/.wheel-probe" "$pin" 2>&1) || probe=1
    rm -rf "$venv/.wheel-probe"
    if [ "$probe" -eq 1 ] && grep -q "(from versions: none)" <<<"$log" \
        && ! grep -qiE "retrying|could not fetch|connection|proxy|ssl" <<<"$log"; then
        echo "$(uname -sm), $("$venv/bin/python" -c 'import sys; print(sys.implementation.cache_tag)'): $(grep 'No matching distribution' <<<"$log")" >"$note"
        echo "no $4 wheel for this platform: $(cat "$note")" >&2
        return 0
    fi
    echo "$log" >&2
    return 1
}
case "${1:-}" in
    "") ;;
    bench) install benches/benches/requirements.txt .installed-bench-requirements pybullet ;;
    plan) install host/planning/peer/requirements.txt .installed-plan-requirements "ompl.geometric, fcl, scipy.spatial" ;;
    cluster) install host/perception/peer/requirements.txt .installed-cluster-requirements "sklearn.cluster" ;;
    slam) install host/slam/peer/requirements.txt .installed-slam-requirements "pybullet, numpy" ;;
    python) install host/python/requirements-test.txt .installed-python-requirements "numpy, pytest, yourdfpy, absl, ipykernel, nbclient" ;;
    record) install host/record/peer/requirements.txt .installed-record-requirements "mcap, rosbags.highlevel, numpy, pyarrow.parquet, pandas, PIL" ;;
    zenoh) install host/bridge/peer/requirements.txt .installed-zenoh-requirements "zenoh, zenoh.ext, rosbags.typesys" ;;
    view) install host/view/peer/requirements.txt .installed-view-requirements "websockets, rosbags.typesys" ;;
    realsense) install_wheel host/peers/realsense/requirements.txt .installed-realsense-requirements "pyrealsense2, numpy" pyrealsense2 ;;
    *) echo "usage: $0 [bench|plan|cluster|slam|python|realsense|record|zenoh|view]" >&2; exit 2 ;;
esac
