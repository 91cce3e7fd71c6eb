#!/usr/bin/env bash
# Builds the OpenCR 1.0 firmware (release), turns the ELF into a raw image and writes it with
# dfu-util through the STM32's own DFU bootloader (USB 0483:df11, alt setting 0) at the start
# of the application area, 0x08040000, leaving ROBOTIS' bootloader in the first 256 KiB
# untouched. The addresses come from boards/opencr/memory.x, which the linker reads too.
#
# Usage: scripts/flash-opencr.sh [--lite] [--check] [--dry-run] [--no-build]
#   --lite      the LoCoBot-Lite build (Create 2 base) instead of the LoCoBot (Kobuki)
#   --check     verify the image: it fits the application area, its vector table's initial
#               stack pointer lies in RAM and its reset vector in the image; print its sha256
#   --dry-run   build and convert, print the dfu-util commands, flash nothing (what CI runs)
#   --no-build  use the ELF last built (scripts/build-boards.sh builds the LoCoBot's) instead
#               of building; refused if it is the other robot's
#
# The image and a copy of its ELF (for `defmt-print -e`, to read the log) are left in
# boards/target/flash/. Put the board in DFU mode first: hold BOOT, press RESET, release BOOT
# (docs/opencr.md).
set -euo pipefail
cd "$(dirname "$0")/.."

die() {
    echo "flash-opencr: $*" >&2
    exit 1
}
# show COMMAND...: print a command, then run it.
show() {
    echo "+ $*"
    "$@"
}

lite=false check=false dry=false build=true
for arg in "$@"; do
    case $arg in
    --lite) lite=true ;;
    --check) check=true ;;
    --dry-run) dry=true ;;
    --no-build) build=false ;;
    -h | --help)
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
        exit 0
        ;;
    *) die "unknown option '$arg' (try --help)" ;;
    esac
done

# region NAME: "ORIGIN LENGTH" of a MEMORY region of memory.x, in bytes.
region() {
    local line origin len unit
    line=$(grep -E "^[[:space:]]*$1[[:space:]]*:" boards/opencr/memory.x) || die "memory.x has no $1 region"
    origin=$(sed -nE 's/.*ORIGIN[[:space:]]*=[[:space:]]*(0x[0-9A-Fa-f]+).*/\1/p' <<<"$line")
    len=$(sed -nE 's/.*LENGTH[[:space:]]*=[[:space:]]*([0-9]+)([KM]?).*/\1/p' <<<"$line")
    unit=$(sed -nE 's/.*LENGTH[[:space:]]*=[[:space:]]*[0-9]+([KM]?).*/\1/p' <<<"$line")
    [ -n "$origin" ] && [ -n "$len" ] || die "cannot read $1's ORIGIN and LENGTH in memory.x: $line"
    case $unit in
    K) len=$((len * 1024)) ;;
    M) len=$((len * 1024 * 1024)) ;;
    esac
    echo "$((origin)) $len"
}
read -r flash_origin flash_len < <(region FLASH)
read -r ram_origin ram_len < <(region RAM)
address=$(printf '0x%08x' "$flash_origin")

# The objcopy of Debian's Rust (rust-web-llvm, which scripts/setup-cross.sh installs), else any
# other that reads ARM ELF files.
find_objcopy() {
    local sysroot host
    if sysroot=$(/usr/bin/rustc --print sysroot 2>/dev/null) &&
        host=$(/usr/bin/rustc -vV 2>/dev/null | sed -n 's/^host: //p') &&
        [ -x "$sysroot/lib/rustlib/$host/bin/rust-objcopy" ]; then
        echo "$sysroot/lib/rustlib/$host/bin/rust-objcopy"
        return
    fi
    for tool in rust-objcopy arm-none-eabi-objcopy llvm-objcopy llvm-objcopy-22; do
        if command -v "$tool" >/dev/null 2>&1; then
            command -v "$tool"
            return
        fi
    done
    die "no objcopy for ARM ELF files: run scripts/setup-cross.sh (Debian's rust-web-llvm has rust-objcopy), or install binutils-arm-none-eabi"
}

elf=boards/target/thumbv7em-none-eabihf/release/board-opencr
name=opencr
features=()
if $lite; then
    name=opencr-lite
    features=(--features locobot-lite)
fi
if $build; then
    echo "building the OpenCR firmware for the $($lite && echo LoCoBot-Lite || echo LoCoBot)"
    # As scripts/build-boards.sh does: from inside the board's workspace, the environment
    # cleared of cargo/rustup variables so that its rust-toolchain.toml applies.
    (cd boards/opencr && show env -u RUSTUP_TOOLCHAIN -u CARGO -u RUSTC -u RUSTC_WRAPPER -u CARGO_TARGET_DIR \
        cargo build --release --quiet "${features[@]}")
fi
[ -f "$elf" ] || die "no firmware at $elf: run scripts/build-boards.sh (or drop --no-build)"

out=boards/target/flash
mkdir -p "$out"
cp "$elf" "$out/$name.elf"
bin=$out/$name.bin
show "$(find_objcopy)" -O binary "$out/$name.elf" "$bin"
# Which robot the image is for: only the LoCoBot-Lite's holds its profile's name,
# "locobot_lite" (firmware/src/config.rs), among its constants.
if grep -a -q locobot_lite "$bin"; then built_lite=true; else built_lite=false; fi
[ "$built_lite" = "$lite" ] ||
    die "$elf was built for the $($built_lite && echo LoCoBot-Lite || echo LoCoBot), not the robot asked for: build it again (drop --no-build)"

# check_image: the checks of --check, on $bin and its ELF.
check_image() {
    local size sp reset entry vt
    size=$(stat -c %s "$bin")
    [ "$size" -gt 8 ] || die "$bin is empty"
    [ "$size" -le "$flash_len" ] ||
        die "$bin is $size bytes; the application area at $address holds $flash_len"
    read -r sp reset < <(od -An -t u4 -N 8 --endian=little "$bin")
    # The initial stack pointer: inside RAM or just past its end (a full descending stack),
    # 8-byte aligned as the AAPCS wants it.
    if [ "$sp" -le "$ram_origin" ] || [ "$sp" -gt $((ram_origin + ram_len)) ] || [ $((sp % 8)) -ne 0 ]; then
        die "initial stack pointer $(printf '0x%08x' "$sp") is not an 8-byte aligned address in RAM ($(printf '0x%08x' "$ram_origin") + $ram_len)"
    fi
    # The reset vector: a Thumb address (bit 0 set) inside the image as it will sit in flash.
    local pc=$((reset & ~1))
    if [ $((reset & 1)) -ne 1 ] || [ "$pc" -lt "$flash_origin" ] || [ "$pc" -ge $((flash_origin + size)) ]; then
        die "reset vector $(printf '0x%08x' "$reset") is not a Thumb address inside the image ($address + $size)"
    fi
    # The ELF agrees: its entry point is that reset handler and its vector table sits at the
    # start of the application area (so the image starts with it).
    if command -v readelf >/dev/null 2>&1 && command -v nm >/dev/null 2>&1; then
        entry=$(readelf -h "$out/$name.elf" | sed -n 's/.*Entry point address:[[:space:]]*//p')
        vt=$(nm "$out/$name.elf" | awk '$3 == "__vector_table" { print "0x" $1 }')
        [ $((entry)) -eq "$reset" ] || die "the ELF's entry point $entry is not the image's reset vector"
        [ $((vt)) -eq "$flash_origin" ] || die "the vector table is at $vt, not at the application area's start $address"
    fi
    printf 'image %s: %d bytes (%d%% of the %d KiB at %s), initial SP 0x%08x, reset 0x%08x\n' \
        "$bin" "$size" $((size * 100 / flash_len)) $((flash_len / 1024)) "$address" "$sp" "$reset"
    echo "sha256 $(sha256sum "$bin" | cut -d' ' -f1)"
}
$check && check_image

flash=(dfu-util -d 0483:df11 -a 0 -s "$address:leave" -D "$bin")
if $dry; then
    echo "dry run, nothing flashed; would run:"
    echo "  dfu-util -l"
    echo "  ${flash[*]}"
    exit 0
fi

command -v dfu-util >/dev/null 2>&1 || die "dfu-util is not installed (Debian and Ubuntu: sudo apt-get install dfu-util)"
listing=$(dfu-util -l 2>&1 || true)
found=$(grep -c 'Found DFU: \[0483:df11\].*alt=0' <<<"$listing" || true)
if [ "$found" -eq 0 ]; then
    die "no STM32 in DFU mode found ('dfu-util -l' lists no 0483:df11). Connect the OpenCR by USB, hold its BOOT button, press and release RESET, then release BOOT; 'lsusb' should then list 'STMicroelectronics STM Device in DFU Mode' (docs/opencr.md)"
fi
[ "$found" -eq 1 ] || die "$found STM32 devices are in DFU mode; leave only the OpenCR connected"
grep -q 'Found DFU: \[0483:df11\].*alt=0.*Internal Flash' <<<"$listing" ||
    echo "flash-opencr: warning: alt setting 0 is not named '@Internal Flash' as the STM32F7's is:"$'\n'"$listing" >&2
show "${flash[@]}" ||
    die "dfu-util failed (above). 'Cannot open DFU device': run as root or add a udev rule for 0483:df11; an error after 'Submitting leave request' is harmless if the board starts (LED USER1 blinks)"
echo "flashed $bin at $address; the board starts it now (if not, press RESET)"
