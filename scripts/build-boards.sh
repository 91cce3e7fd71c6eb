#!/usr/bin/env bash
# Builds the firmware of every board (release) with Debian's toolchain, each in its own
# workspace; prints flash and static RAM. With --clippy, lints every board instead (Debian's
# clippy, release, warnings as errors). The environment is cleared of cargo/rustup variables
# so each board's rust-toolchain.toml applies. Both boards share one target directory
# (boards/target), so the second reuses the host-side build dependencies of the first.
set -euo pipefail
cd "$(dirname "$0")/.."
clippy=false
[ "${1:-}" = "--clippy" ] && clippy=true
board_cargo() { # BOARD ARGS...: cargo in BOARD's workspace, with its own toolchain
    local board=$1
    shift
    (cd "boards/$board" && env -u RUSTUP_TOOLCHAIN -u CARGO -u RUSTC -u RUSTC_WRAPPER -u CARGO_TARGET_DIR \
        cargo "$@")
}
failed=0
for board in mps2-an386 opencr; do
    if $clippy; then
        board_cargo "$board" clippy --release --quiet -- -D warnings || { echo "clippy ($board) failed" >&2; failed=1; }
        continue
    fi
    board_cargo "$board" build --release --quiet
    # Where the host finds it: ferrobot::backend::emulated::{board_elf, DEFAULT_FIRMWARE}.
    elf="boards/target/thumbv7em-none-eabihf/release/board-$board"
    size -A "$elf" | awk -v b="$board" '
        $1==".vector_table"||$1==".text"||$1==".rodata" {flash+=$2}
        $1==".data" {flash+=$2; ram+=$2}
        $1==".bss"||$1==".uninit" {ram+=$2}
        END {printf "%s: flash %d B, static RAM %d B\n", b, flash, ram}'
done
exit $failed
