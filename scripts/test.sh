#!/usr/bin/env bash
# The project's one test command: formatting, clippy, every test of the workspace (unit,
# property, lockstep acceptance and fault tests, the Dynamixel conformance test against
# ROBOTIS' official SDK). Installs what it needs by itself, idempotently.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
step() { printf '\n==> %s\n' "$*"; }

step "toolchain: rustfmt and clippy"
rustup component add rustfmt clippy >/dev/null 2>&1 || true

step "python: ROBOTIS dynamixel-sdk in target/py-venv"
scripts/python-env.sh
export FERROBOT_PYTHON="$PWD/target/py-venv/bin/python"

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy --all-targets -D warnings"
cargo clippy --workspace --all-targets -- -D warnings

step "cargo test"
cargo test --workspace --no-fail-fast

step "done in $(( $(date +%s) - start )) s"
