#!/usr/bin/env bash
# The tests that use real time, real serial ports or real processes talking in real time
# (the HIL tests with the firmware in QEMU, the API over PTYs to `ferrobot sim-firmware`, the
# teleoperation terminal, ROBOTIS' SDK on a PTY, the hostile command lines, the real-time
# pacing), RUNS times in a row beside SPINNERS processes that each keep a core busy: a test
# that needs a quiet machine fails here. Prints each run's result and a summary; the logs of
# failed runs stay in target/stress/. Exits non-zero if any run failed.
#
#   scripts/stress.sh [RUNS=20] [SPINNERS=2] [FILTER=the real-time set]
#
# FILTER is a cargo-nextest filter expression, e.g. 'test(/api_serial/)'.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-20}
spinners=${2:-2}
filter=${3:-'binary(hil) | test(/^api_serial/) | test(/^teleop_pty::/) | test(/^cli_hostile::/) | test(/dynamixel_sdk/) | test(/in_qemu$/) | test(/realtime_pacing/)'}

if ! cargo nextest --version >/dev/null 2>&1; then
    echo "scripts/stress.sh needs cargo-nextest" >&2
    exit 2
fi
# What the selected tests need, as the test command installs it.
scripts/setup-cross.sh >/dev/null
scripts/build-boards.sh >/dev/null
scripts/python-env.sh >/dev/null
export FERROBOT_PYTHON="$PWD/target/py-venv/bin/python"
cargo nextest run --workspace --exclude ferrobot-benches --no-run >/dev/null

pids=()
stop() { [ ${#pids[@]} -eq 0 ] || kill "${pids[@]}" 2>/dev/null || true; }
trap stop EXIT
for _ in $(seq 1 "$spinners"); do
    sh -c 'while :; do :; done' &
    pids+=($!)
done

mkdir -p target/stress
failed=0
for i in $(seq 1 "$runs"); do
    log=target/stress/run-$i.log
    start=$(date +%s)
    if cargo nextest run --workspace --exclude ferrobot-benches --no-fail-fast -E "$filter" >"$log" 2>&1; then
        echo "run $i: green in $(( $(date +%s) - start )) s"
        rm -f "$log"
    else
        failed=$((failed + 1))
        echo "run $i: RED in $(( $(date +%s) - start )) s (log: $log)"
        grep -E '^\s+(FAIL|SIGSEGV|SIGABRT|TIMEOUT) ' "$log" | sort -u || true
    fi
done
echo "$((runs - failed)) of $runs runs green beside $spinners spinning cores"
[ "$failed" -eq 0 ]
