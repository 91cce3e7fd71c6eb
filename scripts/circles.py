#!/usr/bin/env python3
"""Import circles inside each crate of the repository: files that reach each other through
`crate::` and `super::` paths (a `use` or a path in code), grouped as strongly connected
components. The design allows none of more than 3 files.

Usage: scripts/circles.py [--check] [--max N] [CRATE_DIR ...]
Prints every circle of 2 files or more, largest first; `--check` exits with 1 when one is
larger than N (default 3). Tests, examples and benches are left out.
"""
import os
import re
import subprocess
import sys

PATH_RE = re.compile(r"\b(crate|super)((?:::[A-Za-z_][A-Za-z0-9_]*)+)")
GROUP_RE = re.compile(r"\b(crate|super)((?:::[A-Za-z_][A-Za-z0-9_]*)*)::\{")


def module_files(src):
    """Maps module path tuples (crate root = ()) to files."""
    mods = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            full = os.path.join(root, f)
            rel = os.path.relpath(full, src)[:-3].split(os.sep)
            if rel[-1] in ("lib", "main") and len(rel) == 1:
                key = ()
            elif rel[-1] == "mod":
                key = tuple(rel[:-1])
            else:
                key = tuple(rel)
            if rel[0] == "bin":
                continue
            mods[key] = full
    return mods


def strip_tests_and_comments(text):
    out = []
    skip_depth = None
    depth = 0
    pending = False
    for line in text.split("\n"):
        code = re.sub(r"//.*", "", line)
        code = re.sub(r'"([^"\\]|\\.)*"', '""', code)
        if skip_depth is None and "#[cfg(test)]" in line:
            pending = True
        if skip_depth is None and not pending:
            out.append(code)
        for ch in code:
            if ch == "{":
                if pending and skip_depth is None:
                    skip_depth = depth
                    pending = False
                depth += 1
            elif ch == "}":
                depth -= 1
                if skip_depth is not None and depth == skip_depth:
                    skip_depth = None
            elif ch == ";" and pending and skip_depth is None:
                pending = False
    return "\n".join(out)


def resolve(mods, base, parts):
    """The file of the longest module prefix of `base + parts`."""
    path = list(base) + list(parts)
    while path:
        if tuple(path) in mods:
            return mods[tuple(path)]
        path.pop()
    return mods.get(())


def edges_of(mods, key, file):
    text = strip_tests_and_comments(open(file, encoding="utf-8", errors="replace").read())
    parent = key[:-1] if not file.endswith(("mod.rs", "lib.rs", "main.rs")) else key[:-1]
    # A file's own module path is `key`; `super` is its parent module.
    targets = set()
    uses = []
    for m in PATH_RE.finditer(text):
        uses.append((m.group(1), [p for p in m.group(2).split("::") if p]))
    # Groups: `crate::a::{b, c::d}` -> crate::a::b, crate::a::c::d (one level of nesting).
    for m in GROUP_RE.finditer(text):
        start = m.end()
        depth, i = 1, start
        while i < len(text) and depth:
            depth += {"{": 1, "}": -1}.get(text[i], 0)
            i += 1
        inner = text[start:i - 1]
        prefix = [p for p in m.group(2).split("::") if p]
        for item in re.split(r",(?![^{]*\})", inner):
            item = item.strip()
            name = re.match(r"[A-Za-z_][A-Za-z0-9_]*(::[A-Za-z_][A-Za-z0-9_]*)*", item)
            if name:
                uses.append((m.group(1), prefix + name.group(0).split("::")))
    for kind, parts in uses:
        if kind == "crate":
            base = ()
        else:
            base = list(key[:-1])
            while parts and parts[0] == "super":
                parts = parts[1:]
                base = base[:-1]
            base = tuple(base)
        t = resolve(mods, base, parts)
        if t and t != file:
            targets.add(t)
    # The parent module declaring its children is not an import.
    return targets


def sccs(graph):
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    for v in graph:
        if v not in index:
            visit(v)
    return out


def main():
    args = sys.argv[1:]
    check = "--check" in args
    limit = 3
    if "--max" in args:
        limit = int(args[args.index("--max") + 1])
    dirs = [a for a in args if not a.startswith("--") and not a.isdigit()]
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True).stdout.strip() or "."
    os.chdir(root)
    if not dirs:
        dirs = sorted(os.path.dirname(p) for p in subprocess.run(["git", "ls-files", "*Cargo.toml"], capture_output=True, text=True).stdout.split())
    worst = 0
    for d in dirs:
        src = os.path.join(d, "src")
        if not os.path.isdir(src):
            continue
        mods = module_files(src)
        graph = {f: edges_of(mods, k, f) for k, f in mods.items()}
        for comp in sorted(sccs(graph), key=len, reverse=True):
            if len(comp) < 2:
                continue
            worst = max(worst, len(comp))
            mark = "  TOO LARGE" if len(comp) > limit else ""
            print(f"{len(comp):3} files{mark}: " + ", ".join(sorted(os.path.relpath(c) for c in comp)))
    if check and worst > limit:
        sys.exit(1)


if __name__ == "__main__":
    main()
