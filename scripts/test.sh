#!/usr/bin/env bash
# The project's one test command: formatting, clippy, the docs (rustdoc's warnings as errors),
# both board builds (and the OpenCR's flashable image checked), every test of the workspace
# (unit, property, lockstep acceptance and fault tests, the API on the simulator and over serial
# ports, the Dynamixel conformance test against ROBOTIS' official SDK, the planning benchmark's
# exports re-checked by FCL, the Python package's pytest suites against the extension this
# build makes, and the hardware-in-the-loop tests with the firmware in QEMU). Installs what it
# needs by itself, idempotently.
#
# Work that does not need all of the machine runs beside the rest: the Python setup and the
# board builds while the workspace's tests compile, and the HIL tests (QEMU paced at real
# time, about half a core) while the rest of the build and clippy run.
# A background job's output is printed, whole, when it is waited for; every check runs even
# when an earlier one failed, and the script fails at the end naming what failed.
set -euo pipefail
cd "$(dirname "$0")/.."
# Every test's temporary files go to a directory of this run's own, which must be empty at the
# end: a test that leaves files behind fails the run (on a shared disk they pile up run after
# run). A short path, since Unix sockets' paths are limited to 107 bytes.
run_tmp=$(mktemp -d "${TMPDIR:-/tmp}/ferrobot-ci.XXXXXX")
# Readable by all, as /tmp is: the hardware check's permission test runs `ferrobot` as
# `nobody`, who must reach the serial links the test makes here (mktemp's mode is 0700).
chmod 755 "$run_tmp"
export TMPDIR=$run_tmp
echo "disk: $(df -h --output=avail . | tail -1 | tr -d ' ') free where the build goes; temporary files in $TMPDIR"
start=$(date +%s)
last=$start
# Each step's header also says how long the one before it took, so CI time can be read by step.
step() {
    now=$(date +%s)
    printf '\n==> [%4d s, previous step %d s] %s\n' "$(( now - start ))" "$(( now - last ))" "$*"
    last=$now
}

failed=()
# check NAME COMMAND...: run a check; a failure is recorded and reported at the end.
check() {
    local name=$1
    shift
    "$@" || failed+=("$name")
}

# Background jobs, each in its own session (so that it can be stopped whole: cargo, rustc,
# QEMU), with its output in target/ci-logs/NAME.log.
logs=target/ci-logs
mkdir -p "$logs"
declare -A bg_pids=()
background() { # NAME SHELL-COMMAND
    setsid -w bash -c "$2" >"$logs/$1.log" 2>&1 </dev/null &
    bg_pids[$1]=$!
}
# join NAME: wait for a background job, print its output, record its failure.
join() {
    local rc=0
    wait "${bg_pids[$1]}" || rc=$?
    unset "bg_pids[$1]"
    cat "$logs/$1.log"
    [ "$rc" -eq 0 ] || failed+=("$1")
    return 0
}
stop_background() {
    for pid in "${bg_pids[@]}"; do
        kill -- "-$pid" "$pid" 2>/dev/null || true
    done
}
trap stop_background EXIT

step "toolchain: rustfmt and clippy"
rustup component add rustfmt clippy >/dev/null 2>&1 || true

# Before the Python setup: both may need apt, which takes one install at a time.
step "cross toolchain for the boards (Debian's rustc-web, lld, QEMU)"
scripts/setup-cross.sh

step "started: Python (dynamixel-sdk; OMPL and FCL for the planning peer; scikit-learn for the clustering peer; PyBullet for SLAM's independent sequences; pytest, yourdfpy, absl-py and a Jupyter kernel for the Python package's tests; pyrealsense2 for the RealSense server; mcap and rosbags to read our recordings, pyarrow and pandas our LeRobot exports) in target/py-venv, and the board builds, the OpenCR image's check and clippy (mps2-an386 for QEMU, opencr for OpenCR 1.0)"
# Then, in the same job, the sequence the SLAM peer test reads, rendered by PyBullet (100 s of a
# core, most of that test's time) beside the build rather than in the tests' queue after it.
slam_sequence=target/slam-peer/edges-600-seed2
slam_render="--kind edges --frames 600 --seed 2"
background python "scripts/python-env.sh && scripts/python-env.sh plan && scripts/python-env.sh cluster && scripts/python-env.sh slam && scripts/python-env.sh python && scripts/python-env.sh realsense && scripts/python-env.sh record && scripts/python-env.sh zenoh && scripts/python-env.sh view && rm -rf $slam_sequence && target/py-venv/bin/python host/slam/peer/render_sequence.py $slam_render --out $slam_sequence >/dev/null && echo '$slam_render' > $slam_sequence/render-args.txt"

# The boards' clippy (Debian's, -D warnings) right after their builds: both boards share one
# target directory (boards/target), so it reuses the host-side build dependencies, and it keeps
# off the workspace's target directory, whose lock the steps below hold. Between the two, the
# OpenCR's flashing script on the ELF just built (--no-build: no second build): the raw image,
# its checks (size, initial stack pointer, reset vector) and the dfu-util commands it would run.
background boards 'rc=0; scripts/build-boards.sh || rc=1; scripts/flash-opencr.sh --no-build --dry-run --check || rc=1; scripts/build-boards.sh --clippy || rc=1; exit $rc'

step "cargo fmt --check"
check fmt cargo fmt --all -- --check

# The house's budget: files under 600 lines and functions under 80 (tests excepted) unless
# listed with a reason in scripts/budget-exceptions.txt; no import circle of more than three
# files inside a crate.
step "size budget and import circles"
check budget python3 scripts/budget.py --check
check circles python3 scripts/circles.py --check

# Every cargo command below selects the whole workspace (--workspace), as the full build does,
# so that nothing is built twice: a narrower selection (-p) would unify other features. The
# test builds leave out the criterion benchmarks' crate (--exclude ferrobot-benches): no test
# needs criterion, and the rest builds the same without it (sim-stubs' dev-dependencies enable
# the features it adds). Clippy lints it with the rest. `tested` is that one selection.
tested=(--workspace --exclude ferrobot-benches)
step "cargo test --no-run: what the HIL tests need"
# --timings: each build's per-crate times in target/cargo-timings/ (the HTML reports), to see
# where CI's compile time goes.
# Their executables are listed (scripts/test-binaries.py) and run directly below: a background
# `cargo test` would wait for cargo's build lock until the rest of the workspace had compiled
# (4 minutes in CI) before running a test.
hil_binaries=$logs/hil-binaries.txt
cargo test "${tested[@]}" --no-run --timings --message-format=json-render-diagnostics \
    --test hil --test host_run --test pytest --bin firmware-process \
    | python3 scripts/test-binaries.py "$hil_binaries" hil host_run pytest firmware-process

step "waited for: the board builds and their clippy"
join boards
step "waited for: Python"
join python
export FERROBOT_PYTHON="$PWD/target/py-venv/bin/python"
export FERROBOT_SLAM_PEER_SEQUENCE="$PWD/$slam_sequence"

# While the HIL tests run (they keep simulated time with the firmware, so a busy machine only
# makes them take longer), the rest is built and linted (the tests' executables run directly,
# so they start at once rather than after that build); the other tests, some of which run
# on wall-clock budgets (the planners, serial timeouts), run after them, alone. ferrobot-hil's
# library and its firmware-process binary are the harness and hold no tests of their own (the
# binary's empty test harness still runs, here).
# With them, the host-run firmware's tests (hil-tests/tests/host_run.rs: the stock robots on
# emulated devices, and each fault of a real wire on the host-run firmware and in QEMU); and,
# in a job of its own beside them, PyRobot's listings on the host-run firmware
# (FERROBOT_BACKEND=direct-emulated, about six minutes, paced at real time), then through the
# remote backend (two LoCoBots served on zenoh by the test in lockstep with the listings, a
# second process; about a minute and a half of CPU). nextest leaves the listings out below.
host_run_listings=pyrobot_listings_on_the_host_run_firmware
remote_listings=pyrobot_listings_through_the_remote_backend
step "started: the HIL tests (hil-tests/tests/hil.rs: the firmware in QEMU; host_run.rs: the host-run firmware) and PyRobot's listings on the host-run firmware and through the remote backend"
run=scripts/run-test-binary.sh
background hil "rc=0; for t in firmware-process hil host_run; do $run $hil_binaries \$t || rc=1; done; exit \$rc"
background listings "rc=0; for t in $host_run_listings $remote_listings; do $run $hil_binaries pytest --exact \$t || rc=1; done; exit \$rc"

step "cargo test --no-run: every other test"
other_binaries=$logs/other-binaries.txt
cargo test "${tested[@]}" --no-run --timings --message-format=json-render-diagnostics \
    | python3 scripts/test-binaries.py "$other_binaries" ferrobot-cli:integration

# The demo on the host-run firmware of both LoCoBots (ferrobot-cli's demo_host_run: the
# command line's binary, just built, on emulated devices paced at real time, little CPU),
# beside clippy and the docs; nextest leaves it out below.
host_run_demos=demo_host_run
step "started: the demo on the host-run firmware (ferrobot-cli's $host_run_demos), real-time paced"
background demos "$run $other_binaries ferrobot-cli:integration $host_run_demos"

# Clippy (every target, -D warnings; the workspace includes the fuzz targets, fuzz/, built
# without libFuzzer as programs that replay inputs, so they are linted too), then the docs
# (rustdoc's warnings as errors: a broken intra-doc link fails; right after clippy, whose
# dependency metadata cargo doc reuses where the features agree), then a user's program with
# one backend (the simulator without serial-port libraries, the serial port without the
# simulator: two small check builds of the API crate with other features).
lint="rc=0
cargo clippy --workspace --all-targets -- -D warnings || { echo 'FAILED: clippy'; rc=1; }
RUSTDOCFLAGS='-D warnings' cargo doc ${tested[*]} --no-deps || { echo 'FAILED: cargo doc'; rc=1; }
scripts/backend-builds.sh || { echo 'FAILED: backend builds'; rc=1; }
exit \$rc"

# cargo-nextest (on every machine of this kind; cargo's own runner where it is missing) runs
# the tests of all binaries in one queue, two at a time: cargo test runs one binary after the
# other, and a binary whose last test is long leaves the second core idle until it ends.
# The slowest tests start first (.config/nextest.toml), for the same reason.
# Nextest does not run doc tests: cargo runs them after it.
#
# With nextest, the lint job runs beside the tests: nextest runs the binaries built above from
# their list (--binaries-metadata, made first, which compiles nothing), so it never waits for
# cargo's build lock, which clippy holds. Beside a busy core the two together get more of the
# machine than one after the other (CI, 2 cores: about 140 s less), and the tests keep
# simulated time, so a busier machine only makes them take longer.
if cargo nextest --version >/dev/null 2>&1; then
    step "nextest's list of every other test's binaries (built above: nothing is compiled)"
    nextest_binaries=$logs/nextest-binaries.json
    nextest_metadata=$logs/cargo-metadata.json
    check "nextest list" cargo nextest list "${tested[@]}" --exclude ferrobot-hil \
        --list-type binaries-only --message-format json >"$nextest_binaries"
    check "cargo metadata" cargo metadata --format-version 1 --all-features --no-deps \
        >"$nextest_metadata"
    step "started: cargo clippy --all-targets -D warnings, cargo doc -D warnings, and ferrobot with one backend each (sim without serialport, serial without the simulator)"
    background lint "$lint"
    step "waited for: the HIL tests, PyRobot's listings and the demo on the host-run firmware"
    join hil
    join listings
    join demos
    step "cargo nextest run: every other test"
    check "cargo nextest" cargo nextest run --binaries-metadata "$nextest_binaries" \
        --cargo-metadata "$nextest_metadata" --no-fail-fast \
        -E "not test(=$host_run_listings) and not test(=$remote_listings) and not test(/$host_run_demos/)"
    step "waited for: clippy, the docs and the one-backend builds"
    join lint
    step "cargo test --doc"
    check "cargo test --doc" cargo test "${tested[@]}" --doc --exclude ferrobot-hil
else
    step "cargo clippy, cargo doc and ferrobot with one backend each"
    check lint bash -c "$lint"
    step "waited for: the HIL tests, PyRobot's listings and the demo on the host-run firmware"
    join hil
    join listings
    join demos
    step "cargo test: every other test (cargo-nextest is not installed)"
    check "cargo test" cargo test "${tested[@]}" --no-fail-fast --exclude ferrobot-hil -- \
        --skip "$host_run_listings" --skip "$remote_listings" --skip "$host_run_demos"
fi

step "what the tests left in the temporary directory, and the build's size on disk"
left=$(find "$run_tmp" -mindepth 1 -maxdepth 1 -printf '%f\n' | sort)
if [ -n "$left" ]; then
    echo "left behind in $run_tmp:"
    echo "$left" | sed 's/^/    /'
    failed+=("temporary files left behind")
else
    rmdir "$run_tmp"
fi
echo "target/: $(du -sh target | cut -f1); $(df -h --output=avail . | tail -1 | tr -d ' ') free"

if [ ${#failed[@]} -gt 0 ]; then
    step "FAILED: ${failed[*]}"
    exit 1
fi
step "done in $(( $(date +%s) - start )) s"
