#!/usr/bin/env python3
"""The test executables a `cargo test --no-run --message-format=json` build made.

Usage: cargo test ... --no-run --message-format=json-render-diagnostics \
           | scripts/test-binaries.py OUT NAME...

Writes to OUT one line per test target named NAME (a `--test` or a `--bin` harness; PACKAGE:NAME
where several packages have a target of that name, as `integration`): the name as given,
the package's directory and the executable, tab-separated (scripts/run-test-binary.sh reads it), so that the test command can run them
itself, each from its package's directory as cargo would. Run that way, a background job does
not wait for cargo's build lock while the rest of the workspace compiles beside it. Passes the
build's rendered diagnostics (stderr) through; fails when a NAME was not built.
"""

import json
import os
import sys


def package_name(package_id):
    """The package's name in a cargo package id (`path+file:///dir/cli#ferrobot-cli@0.1.0`, or
    `path+file:///dir/ferrobot#0.1.0` where the directory is named after the package)."""
    path, _, frag = package_id.partition("#")
    if "@" in frag:
        return frag.split("@")[0]
    return path.rstrip("/").rsplit("/", 1)[-1]


def main():
    out, names = sys.argv[1], set(sys.argv[2:])
    found = {}
    for line in sys.stdin:
        try:
            m = json.loads(line)
        except json.JSONDecodeError:
            sys.stdout.write(line)
            continue
        if m.get("reason") != "compiler-artifact" or not m.get("executable"):
            continue
        if not m.get("profile", {}).get("test"):
            continue
        target = m["target"]["name"]
        for name in (target, f"{package_name(m['package_id'])}:{target}"):
            if name in names:
                found[name] = (os.path.dirname(m["manifest_path"]), m["executable"])
    missing = names - set(found)
    if missing:
        sys.exit(f"test-binaries: not built: {', '.join(sorted(missing))}")
    with open(out, "w") as f:
        for name in sorted(found):
            f.write("\t".join((name,) + found[name]) + "\n")


if __name__ == "__main__":
    main()
