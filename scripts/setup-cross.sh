#!/usr/bin/env bash
# Installs the Cortex-M cross toolchain the boards build with, idempotently: Debian's Rust
# (rustc-web/cargo-web with the std sources, for -Zbuild-std=core, and its clippy), lld-22 (rust-lld) and QEMU
# for the mps2-an386 board, registered with rustup as the toolchain `debian`.
set -euo pipefail
need=()
[ -x /usr/bin/rustc ] && /usr/bin/rustc --version 2>/dev/null | grep -q '^rustc 1\.9[6-9]' || need+=(rustc-web cargo-web)
[ -d /usr/lib/rustlib/src/rust/library/core ] || need+=(rust-web-src)
dpkg -s rust-web-llvm >/dev/null 2>&1 || need+=(rust-web-llvm)
[ -x /usr/bin/cargo-clippy ] || need+=(rust-web-clippy)
command -v rust-lld >/dev/null 2>&1 || [ -x /usr/bin/rust-lld ] || need+=(lld-22)
command -v qemu-system-arm >/dev/null 2>&1 || need+=(qemu-system-arm)
if [ ${#need[@]} -gt 0 ]; then
    echo "installing: ${need[*]}" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" lld-22 >/dev/null
fi
# rust-lld: lld-22 installs ld.lld-22; rustc looks for rust-lld.
if ! command -v rust-lld >/dev/null 2>&1 && [ ! -x /usr/bin/rust-lld ]; then
    lld=$(command -v ld.lld-22 || command -v ld.lld || true)
    [ -n "$lld" ] && ln -sf "$lld" /usr/bin/rust-lld
fi
rustup toolchain list | grep -q '^debian' || rustup toolchain link debian /usr
echo "cross toolchain: $(/usr/bin/rustc --version), $(qemu-system-arm --version | head -1)"
