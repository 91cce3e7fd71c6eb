#!/usr/bin/env bash
# Creates target/lerobot-venv with LeRobot (host/record/peer/requirements-lerobot.txt), the
# reference reader of Ferrobot's LeRobot exports, for `scripts/lerobot-check.sh`. LeRobot needs
# Python 3.12 or newer and brings torch (CPU wheels): about 2 GB, so it is not part of the fast
# suite. Idempotent: does nothing when it is already there.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/lerobot-venv
req=host/record/peer/requirements-lerobot.txt
if [ ! -x "$venv/bin/python" ]; then
    py=""
    for c in python3.13 python3.12 python3; do
        if command -v "$c" >/dev/null 2>&1 \
            && "$c" -c 'import sys; sys.exit(sys.version_info < (3, 12))' 2>/dev/null; then
            py=$c
            break
        fi
    done
    if [ -z "$py" ]; then
        # pyenv keeps versions it does not put on the PATH.
        for c in "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.1[2-9]*/bin/python3; do
            [ -x "$c" ] && py=$c && break
        done
    fi
    if [ -z "$py" ]; then
        echo "LeRobot needs Python 3.12 or newer; none found" >&2
        exit 1
    fi
    mkdir -p target
    "$py" -m venv "$venv"
fi
if ! cmp -s "$req" "$venv/.installed-requirements" 2>/dev/null; then
    "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$req"
    cp "$req" "$venv/.installed-requirements"
fi
"$venv/bin/python" -c "import lerobot.datasets.lerobot_dataset"
