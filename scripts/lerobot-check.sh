#!/usr/bin/env bash
# LeRobot's own loader on a Ferrobot export (issue 52; outside the fast suite, because LeRobot
# brings torch): records two demonstrations of the simulated LoCoBot and exports them (the
# integration test `lerobot::demonstrations_export_…`, which also checks the export with
# pyarrow, pandas and rosbags), then loads the dataset with `LeRobotDataset` in
# target/lerobot-venv (scripts/lerobot-env.sh) and checks what it serves
# (host/record/peer/check_lerobot.py). About 2 minutes once the environments exist; the
# first run downloads about 3 GB.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/python-env.sh record
bash scripts/lerobot-env.sh
FERROBOT_PYTHON="$PWD/target/py-venv/bin/python" cargo test -q -p ferrobot-record \
    --test integration lerobot::demonstrations_export -- --nocapture
# LeRobot's stderr (torchcodec's warnings where FFmpeg's libraries are missing: no video here)
# goes to a log, shown when the check fails.
log=target/lerobot-check.stderr
if ! target/lerobot-venv/bin/python host/record/peer/check_lerobot.py \
    target/tmp/lerobot-export/dataset 30 "reach and grasp,push with the wrist" 2>"$log"; then
    tail -20 "$log" >&2
    exit 1
fi
