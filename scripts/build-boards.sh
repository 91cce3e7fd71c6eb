#!/usr/bin/env bash
# Builds the firmware of every board (release) with Debian's toolchain, each in its own
# workspace; prints flash and static RAM. The environment is cleared of cargo/rustup
# variables so each board's rust-toolchain.toml applies.
set -euo pipefail
cd "$(dirname "$0")/.."
for board in mps2-an386 opencr; do
    (cd "boards/$board" && env -u RUSTUP_TOOLCHAIN -u CARGO -u RUSTC -u RUSTC_WRAPPER -u CARGO_TARGET_DIR \
        cargo build --release --quiet)
    # Where the host finds it: ferrobot::backend::emulated::{board_elf, DEFAULT_FIRMWARE}.
    elf="boards/target/thumbv7em-none-eabihf/release/board-$board"
    size -A "$elf" | awk -v b="$board" '
        $1==".vector_table"||$1==".text"||$1==".rodata" {flash+=$2}
        $1==".data" {flash+=$2; ram+=$2}
        $1==".bss"||$1==".uninit" {ram+=$2}
        END {printf "%s: flash %d B, static RAM %d B\n", b, flash, ram}'
done
