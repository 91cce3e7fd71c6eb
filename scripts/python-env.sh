#!/usr/bin/env bash
# Creates target/py-venv with the Python packages the conformance tests need (ROBOTIS'
# official Dynamixel SDK). Idempotent: does nothing when they are already there.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/py-venv
req=sim-stubs/tests/conformance/requirements.txt
if [ ! -x "$venv/bin/python" ]; then
    mkdir -p target
    if ! python3 -m venv "$venv" 2>/dev/null; then
        echo "python3 -m venv failed; installing python3-venv" >&2
        apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
        python3 -m venv "$venv"
    fi
fi
if ! cmp -s "$req" "$venv/.installed-requirements" 2>/dev/null; then
    "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$req"
    cp "$req" "$venv/.installed-requirements"
fi
"$venv/bin/python" -c "import dynamixel_sdk" 
