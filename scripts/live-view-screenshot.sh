#!/usr/bin/env bash
# A screenshot of a live Ferrobot view in Lichtblick (the open-source fork of Foxglove Studio),
# for docs/zenoh.md: docs/img/live-view-lichtblick.png.
#
#   LICHTBLICK_WEB=/path/to/lichtblick/web/.webpack bash scripts/live-view-screenshot.sh
#
# LICHTBLICK_WEB is a web build of Lichtblick, as for scripts/viewer-screenshot.sh (which says
# how to make one). What it does:
#   - apt: chromium; npm: scripts/viewer's pinned playwright-core (each once);
#   - runs host/view/examples/tabletop_live.rs: the simulated LoCoBot at the tabletop scene's
#     table, its view served on 127.0.0.1:$VIEW_PORT (Foxglove's WebSocket protocol);
#   - node scripts/viewer/screenshot.mjs --live: Lichtblick opens a Foxglove WebSocket
#     connection to it with scripts/viewer/live-layout.json (3D with the URDF, /tf, the scene's
#     markers and the planned path; the colour image; a plot of /joint_states). Once the view
#     has a viewer, the example plans a reach over the table, sets the arm off along it and
#     stops it half way, the robot's time then standing still; the screenshot is taken once the
#     page has stopped changing.
#
# Variables: LICHTBLICK_WEB (required), OUT (docs/img/live-view-lichtblick.png), WIDTH (1600),
# HEIGHT (1000), THEME (light), CHROMIUM (/usr/bin/chromium), PORT (47614: the page's server),
# VIEW_PORT (47615: the live view's).
set -euo pipefail
cd "$(dirname "$0")/.."

. scripts/viewer/setup.sh
OUT=${OUT:-docs/img/live-view-lichtblick.png}
VIEW_PORT=${VIEW_PORT:-47615}

echo "== building the example"
cargo build -q --release -p ferrobot-view --example tabletop_live
work=$(mktemp -d)
trap 'exec 3>&- 2>/dev/null || true; kill "$pid" 2>/dev/null || true; rm -rf "$work"' EXIT
mkfifo "$work/in"
target/release/examples/tabletop_live "127.0.0.1:$VIEW_PORT" <"$work/in" >"$work/out" &
pid=$!
exec 3>"$work/in"
# The example's lines: SERVING, then FROZEN once the robot stands still.
until grep -q '^SERVING ' "$work/out"; do
  kill -0 "$pid" 2>/dev/null || { echo "the example ended" >&2; exit 1; }
  sleep 0.2
done
( until grep -q '^FROZEN' "$work/out"; do sleep 0.2; done; touch "$work/frozen" ) &

echo "== screenshot: the live view on ws://127.0.0.1:$VIEW_PORT in $LICHTBLICK_WEB"
node scripts/viewer/screenshot.mjs \
  --web "$LICHTBLICK_WEB" \
  --live "ws://127.0.0.1:$VIEW_PORT" \
  --layout scripts/viewer/live-layout.json \
  --wait-for "$work/frozen" \
  --out "$OUT" \
  --width "${WIDTH:-1600}" \
  --height "${HEIGHT:-1000}" \
  --theme "${THEME:-light}" \
  --port "${PORT:-47614}" \
  --chromium "$CHROMIUM"
exec 3>&-
wait "$pid"
