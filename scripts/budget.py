#!/usr/bin/env python3
"""The house's size budget: source files over 600 lines and functions over 80 lines.

Counts the lines of every `.rs` file of the repository outside `tests/`, `benches/`, `fuzz/`,
`examples/` and `target/`, leaving out `#[cfg(test)]` modules (tests are excepted from the
budget). A function's length runs from its `fn` line to its closing brace, found by counting
braces outside strings, chars and comments. Prints the files and functions over budget,
largest first; `--check` exits with 1 if any is over budget and not listed in
`scripts/budget-exceptions.txt` (one `path` or `path::function` per line, `#` comments).

Also checks that no unit test is silently left out: a crate whose library is not built as a
test harness (`[lib] test = false` in its Cargo.toml, where its tests live in `tests/` to spare
CI a second compile of an optimised library) holds no `#[cfg(test)]` or `#[test]` in `src/`.

Usage: scripts/budget.py [--check] [--files N] [--fns N]
"""
import os
import re
import subprocess
import sys

FILE_BUDGET = 600
FN_BUDGET = 80
SKIP = ("/tests/", "/benches/", "/fuzz/", "/examples/", "target/")
FN_RE = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"[^\"]*\"\s+)?fn\s+([A-Za-z_][A-Za-z0-9_]*)")


def strip_line(line, state):
    """Returns the line's code with strings, chars and comments blanked; state carries block
    comments and raw strings across lines."""
    out = []
    i = 0
    n = len(line)
    while i < n:
        if state["block"]:
            j = line.find("*/", i)
            if j < 0:
                return "".join(out)
            state["block"] = False
            i = j + 2
            continue
        if state["str"]:
            end = state["str"]
            if end == '"':
                if line[i] == "\\":
                    i += 2
                    continue
                if line[i] == '"':
                    state["str"] = None
                i += 1
                continue
            j = line.find(end, i)
            if j < 0:
                return "".join(out)
            state["str"] = None
            i = j + len(end)
            continue
        c = line[i]
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            state["block"] = True
            i += 2
            continue
        m = re.match(r'r(#*)"', line[i:])
        if m and (i == 0 or not (line[i - 1].isalnum() or line[i - 1] == "_")):
            state["str"] = '"' + m.group(1)
            i += len(m.group(0))
            continue
        if c == '"':
            state["str"] = '"'
            i += 1
            continue
        if c == "'":
            m = re.match(r"'(\\.|[^\\'])'|'\\u\{[0-9a-fA-F]+\}'|'\\x[0-9a-fA-F]{2}'", line[i:])
            if m:
                i += len(m.group(0))
                continue
        out.append(c)
        i += 1
    return "".join(out)


def measure(path):
    """(non-test lines, [(fn name, start line, length)])."""
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = f.read().split("\n")
    state = {"block": False, "str": None}
    code = [strip_line(l, state) for l in lines]
    depth = 0
    test_until = None  # depth at which a cfg(test) module ends
    pending_test = False
    count = 0
    fns = []
    stack = []  # (name, start, depth at fn line)
    pending_fn = None
    for idx, (raw, c) in enumerate(zip(lines, code)):
        in_test = test_until is not None
        if not in_test:
            if raw.strip():
                count += 1
            if "#[cfg(test)]" in raw:
                pending_test = True
            m = FN_RE.match(c)
            if m:
                pending_fn = (m.group(7), idx + 1, depth)
        for ch in c:
            if ch == "{":
                if pending_test and test_until is None:
                    test_until = depth
                    pending_test = False
                if pending_fn is not None:
                    stack.append(pending_fn)
                    pending_fn = None
                depth += 1
            elif ch == "}":
                depth -= 1
                if test_until is not None and depth == test_until:
                    test_until = None
                if stack and stack[-1][2] == depth:
                    name, start, _ = stack.pop()
                    fns.append((name, start, idx + 1 - start + 1))
            elif ch == ";":
                if pending_fn is not None and pending_fn[2] == depth:
                    pending_fn = None  # a declaration without a body
                if pending_test and test_until is None and depth >= 0:
                    pending_test = False  # e.g. `#[cfg(test)] mod x;` or `use`
    return count, fns


def unit_tests_never_run(files):
    """The `src/` files holding tests of crates whose library is not a test harness."""
    found = []
    for manifest in subprocess.run(["git", "ls-files", "*Cargo.toml"], capture_output=True,
                                   text=True).stdout.split():
        text = open(manifest).read()
        if not re.search(r"^\[lib\][^\[]*^test\s*=\s*false", text, re.M | re.S):
            continue
        crate = os.path.dirname(manifest)
        src = os.path.join(crate, "src") + "/"
        tested = included_by_tests(files, crate)
        for f in files:
            if (f.startswith(src) and f not in tested
                    and re.search(r"#\[(cfg\()?test\]?\)?\]", open(f).read())):
                found.append(f)
    return found


def included_by_tests(files, crate):
    """The files that a test target of `crate` (under its `tests/`) compiles by
    `#[path = "..."]`: their unit tests run in that target."""
    tests = os.path.join(crate, "tests") + "/"
    out = set()
    for f in files:
        if f.startswith(tests):
            for rel in re.findall(r'#\[path\s*=\s*"([^"]+)"\]', open(f).read()):
                out.add(os.path.normpath(os.path.join(os.path.dirname(f), rel)))
    return out


def main():
    args = sys.argv[1:]
    check = "--check" in args
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True).stdout.strip() or "."
    os.chdir(root)
    tracked = subprocess.run(["git", "ls-files", "*.rs"], capture_output=True, text=True).stdout.split()
    files = [f for f in tracked if not any(s in "/" + f for s in SKIP)]
    exceptions = set()
    if os.path.exists("scripts/budget-exceptions.txt"):
        for line in open("scripts/budget-exceptions.txt"):
            line = line.split("#")[0].strip()
            if line:
                exceptions.add(line)
    over_files, over_fns = [], []
    for f in files:
        n, fns = measure(f)
        if n > FILE_BUDGET:
            over_files.append((n, f))
        for name, start, length in fns:
            if length > FN_BUDGET:
                over_fns.append((length, f"{f}::{name}", start))
    over_files.sort(reverse=True)
    over_fns.sort(reverse=True)
    bad = 0
    print(f"files over {FILE_BUDGET} lines (tests excepted): {len(over_files)}")
    for n, f in over_files:
        mark = " (listed exception)" if f in exceptions else ""
        bad += not mark
        print(f"  {n:5}  {f}{mark}")
    print(f"functions over {FN_BUDGET} lines: {len(over_fns)}")
    for n, name, start in over_fns:
        mark = " (listed exception)" if name in exceptions else ""
        bad += not mark
        print(f"  {n:5}  {name} (line {start}){mark}")
    never = unit_tests_never_run(tracked)
    for f in never:
        print(f"  {f}: unit tests in a library built with `test = false` (they never run)")
    if check and (bad or never):
        print(f"{bad} over budget and not in scripts/budget-exceptions.txt; "
              f"{len(never)} files of tests that never run")
        sys.exit(1)


if __name__ == "__main__":
    main()
