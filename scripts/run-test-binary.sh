#!/usr/bin/env bash
# run-test-binary.sh LIST NAME [ARGS...]: run the test executable NAME that
# scripts/test-binaries.py listed in LIST, from its package's directory as cargo test does,
# with ARGS for the test harness. Prints cargo's "Running" line first.
set -euo pipefail
list=$1
name=$2
shift 2
line=$(awk -F'\t' -v n="$name" '$1 == n' "$list")
[ -n "$line" ] || { echo "run-test-binary: $name is not in $list" >&2; exit 1; }
dir=$(printf '%s' "$line" | cut -f2)
exe=$(printf '%s' "$line" | cut -f3)
echo "     Running $name ($exe)"
cd "$dir"
exec "$exe" "$@"
