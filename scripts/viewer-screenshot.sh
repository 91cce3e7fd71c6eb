#!/usr/bin/env bash
# A screenshot of a Ferrobot recording opened in Lichtblick (the open-source fork of Foxglove
# Studio), for docs/recording.md: docs/img/recording-lichtblick.png.
#
#   LICHTBLICK_WEB=/path/to/lichtblick/web/.webpack bash scripts/viewer-screenshot.sh
#
# LICHTBLICK_WEB is a web build of Lichtblick: the directory holding its index.html (in a
# Lichtblick checkout, web/.webpack after its production web build; see Lichtblick's README).
# This project does not build Lichtblick itself.
#
# What it does, each step skipped when already done:
#   - apt: chromium (headless, driven by playwright-core; no browser download);
#   - npm: scripts/viewer's pinned playwright-core;
#   - the recording: $RECORDING if given, else target/viewer/tabletop.mcap, made once by the
#     example host/record/examples/tabletop_recording.rs (the LoCoBot at the tabletop scene's
#     table: head down, the arm reaching, the gripper closing and opening, the base turning);
#   - node scripts/viewer/screenshot.mjs: serves the build and the recording on 127.0.0.1 only,
#     opens the recording with scripts/viewer/layout.json (3D with the URDF and /tf, the colour
#     image, a plot of /joint_states), waits until the panels have drawn and stopped changing,
#     and writes $OUT.
#
# Variables: LICHTBLICK_WEB (required), RECORDING, OUT (docs/img/recording-lichtblick.png),
# WIDTH (1600), HEIGHT (1000), AT (0.75: where in the recording, 0 its start, 1 its end),
# THEME (light), CHROMIUM (/usr/bin/chromium), PORT (47613: the local server's, fixed so that the
# URL in Lichtblick's app bar, and so the PNG, is the same from run to run; 0 for any free one).
set -euo pipefail
cd "$(dirname "$0")/.."

. scripts/viewer/setup.sh
OUT=${OUT:-docs/img/recording-lichtblick.png}

if [ -z "${RECORDING:-}" ]; then
  RECORDING=target/viewer/tabletop.mcap
  if [ ! -f "$RECORDING" ]; then
    echo "== recording the LoCoBot at the table: $RECORDING"
    mkdir -p target/viewer
    rm -f "$RECORDING.part"
    cargo run -q -p ferrobot-record --example tabletop_recording -- "$RECORDING.part"
    mv "$RECORDING.part" "$RECORDING"
  fi
fi

echo "== screenshot: $RECORDING in $LICHTBLICK_WEB"
node scripts/viewer/screenshot.mjs \
  --web "$LICHTBLICK_WEB" \
  --recording "$RECORDING" \
  --layout scripts/viewer/layout.json \
  --out "$OUT" \
  --width "${WIDTH:-1600}" \
  --height "${HEIGHT:-1000}" \
  --at "${AT:-0.75}" \
  --theme "${THEME:-light}" \
  --port "${PORT:-47613}" \
  --chromium "$CHROMIUM"
