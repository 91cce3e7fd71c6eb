#!/usr/bin/env bash
# The project's one test command: formatting, clippy, both board builds, every test of the
# workspace (unit, property, lockstep acceptance and fault tests, the API on the simulator and
# over serial ports, the Dynamixel conformance test against ROBOTIS' official SDK, the
# planning benchmark's exports re-checked by FCL, and the hardware-in-the-loop tests with the
# firmware in QEMU). Installs what it needs by itself, idempotently.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
last=$start
# Each step's header also says how long the one before it took, so CI time can be read by step.
step() {
    now=$(date +%s)
    printf '\n==> [%4d s, previous step %d s] %s\n' "$(( now - start ))" "$(( now - last ))" "$*"
    last=$now
}

step "toolchain: rustfmt and clippy"
rustup component add rustfmt clippy >/dev/null 2>&1 || true

step "python: ROBOTIS dynamixel-sdk in target/py-venv"
scripts/python-env.sh
export FERROBOT_PYTHON="$PWD/target/py-venv/bin/python"

step "python: OMPL and FCL for the planning benchmark's peer (host/planning/peer) in target/py-venv"
scripts/python-env.sh plan

step "cross toolchain for the boards (Debian's rustc-web, lld, QEMU)"
scripts/setup-cross.sh

step "board builds: mps2-an386 (QEMU) and opencr (OpenCR 1.0)"
scripts/build-boards.sh

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy --all-targets -D warnings (workspace, fuzz targets, both boards)"
cargo clippy --workspace --all-targets -- -D warnings
# The fuzz targets share the workspace's target directory and dev profile, so only they and
# the fuzzing crates are checked again; clippy does not link, so libFuzzer's C++ need not be
# compiled (libfuzzer-sys then only names a library to link).
(cd fuzz && CARGO_TARGET_DIR=../target CUSTOM_LIBFUZZER_PATH="$PWD/../target/no-libfuzzer/libfuzzer.a" \
    cargo clippy --all-targets -- -D warnings)
for board in mps2-an386 opencr; do
    (cd "boards/$board" && env -u RUSTUP_TOOLCHAIN -u CARGO -u RUSTC -u RUSTC_WRAPPER -u CARGO_TARGET_DIR \
        cargo clippy --release --quiet -- -D warnings)
done

step "cargo test"
cargo test --workspace --no-fail-fast

step "done in $(( $(date +%s) - start )) s"
