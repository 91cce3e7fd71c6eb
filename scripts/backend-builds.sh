#!/usr/bin/env bash
# The API crate with one backend each, as a user's program would build it: with the default
# `sim` backend alone, no serial port library (serialport, nix) is built; with `serial` alone,
# no simulator (ferrobot-sim, rapier3d). Both build an example program.
set -euo pipefail
cd "$(dirname "$0")/.."

absent() { # absent FEATURES CRATE: CRATE is not in ferrobot's normal dependencies with FEATURES
    local features=$1 crate=$2
    if cargo tree -p ferrobot $features -e normal --prefix none 2>/dev/null | grep -q "^$crate "; then
        echo "ferrobot $features depends on $crate" >&2
        return 1
    fi
    echo "ferrobot ${features:-(default: sim)}: no $crate"
}

absent "" serialport
absent "" nix
absent "--no-default-features --features serial" ferrobot-sim
absent "--no-default-features --features serial" rapier3d
cargo check --quiet -p ferrobot --example quickstart
echo "ferrobot (sim): the quickstart builds"
cargo check --quiet -p ferrobot --no-default-features --features serial --example serial_robot
echo "ferrobot --no-default-features --features serial: the serial_robot example builds"
absent "--no-default-features --features direct" ferrobot-sim
cargo check --quiet -p ferrobot --no-default-features --features direct
echo "ferrobot --no-default-features --features direct: the host-run firmware builds without the simulator"
