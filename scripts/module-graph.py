#!/usr/bin/env python3
"""Import cycles between sibling modules, and the longest functions, per crate.

    scripts/module-graph.py [--crates contract,inference,daemon,generator] [--top 10] [--edges] [--check]

For every module directory of every crate it builds the graph among the
directory's child modules: child A points at child B when code anywhere in
A's subtree names `crate::…::B`, `super::B` or `self::B` (grouped `use`
statements included). A child referring back to its own parent is the normal
Rust shape and is not an edge. Test code (`tests.rs` files and `#[cfg(test)]`
modules) is left out. It prints each strongly connected component of more
than one module (an import circle), then the daemon's imports between its
layers that docs/ARCHITECTURE.md does not allow, then the longest functions
outside tests. Exit status 0 unless `--check` (as CI runs it) finds a circle
or a forbidden layer import.
"""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def module_path(src: Path, file: Path) -> tuple[str, ...]:
    """`src/store/mod.rs` → ("store",), `src/lib.rs` → ()."""
    rel = file.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib", "main"):
        parts.pop()
    return tuple(parts)


def strip_tests(text: str) -> str:
    """Drop `#[cfg(test)] mod … { … }` blocks (brace-matched)."""
    out, i = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]\s*(?:pub\s+)?mod\s+\w+\s*(\{|;)", text):
        if m.start() < i:
            continue
        out.append(text[i : m.start()])
        if m.group(1) == ";":
            i = m.end()
            continue
        depth, j = 1, m.end()
        while j < len(text) and depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        i = j
    out.append(text[i:])
    return "".join(out)


def strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def expand_use_tree(prefix: str, tree: str) -> list[str]:
    """`a::{b, c::{d}}` → ["a::b", "a::c::d"]."""
    tree = tree.strip()
    brace = tree.find("{")
    if brace < 0:
        return [f"{prefix}{tree}"]
    head, body = tree[:brace], tree[brace + 1 : tree.rfind("}")]
    items, depth, cur = [], 0, ""
    for ch in body:
        if ch == "," and depth == 0:
            items.append(cur)
            cur = ""
            continue
        depth += {"{": 1, "}": -1}.get(ch, 0)
        cur += ch
    items.append(cur)
    paths = []
    for item in items:
        if item.strip():
            paths += expand_use_tree(prefix + head, item)
    return paths


def referenced_paths(text: str) -> list[str]:
    paths = []
    for m in re.finditer(r"\buse\s+((?:crate|super|self)(?:::\w+)*::\{.*?\});", text, re.S):
        paths += expand_use_tree("", re.sub(r"\s+", "", m.group(1)))
    for m in re.finditer(r"\b(?:crate|super|self)(?:::\w+)+", text):
        paths.append(m.group(0))
    return paths


def resolve(path: str, here: tuple[str, ...], is_dir_module: bool) -> tuple[str, ...] | None:
    """The absolute module path a `crate::`/`super::`/`self::` path starts with."""
    segs = path.split("::")
    if segs[0] == "crate":
        base, rest = [], segs[1:]
    else:
        # Inside `a/b.rs` (module a::b) `self` is a::b and `super` is a; in
        # `a/mod.rs` the same holds with the module being `a`.
        base = list(here)
        rest = segs
        while rest and rest[0] in ("self", "super"):
            if rest[0] == "super":
                if not base:
                    return None
                base.pop()
            rest = rest[1:]
    _ = is_dir_module
    return tuple(base + rest)


def sccs(nodes: list[str], edges: dict[str, set[str]]) -> list[list[str]]:
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
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
            out.append(sorted(comp))

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return [c for c in out if len(c) > 1]


# The daemon's top-level modules and the ones each may import
# (docs/ARCHITECTURE.md, "The daemon's layers"): data flows one way, and no
# layer imports a sibling layer.
DAEMON_LAYERS = {
    "cli": {"config", "counting", "domain", "files", "ops", "pipeline", "sinks", "store"},
    "pipeline": {"config", "counting", "domain", "files", "store"},
    "ops": {"config", "counting", "domain", "files", "store"},
    "sinks": {"config", "domain", "files", "store"},
    "store": {"config", "domain", "files"},
    "counting": {"config", "domain", "store"},
    "config": {"domain", "files"},
    "domain": set(),
    "files": set(),
}


def module_refs(crate: str) -> tuple[dict, dict]:
    """Every module of `crate` and the modules each refers to (tests aside)."""
    src = ROOT / crate / "src"
    files = sorted(p for p in src.rglob("*.rs") if p.name != "tests.rs")
    modules = {module_path(src, f): f for f in files}
    refs: dict[tuple[str, ...], set[tuple[str, ...]]] = defaultdict(set)
    for mod, f in modules.items():
        text = strip_comments(strip_tests(f.read_text()))
        for p in referenced_paths(text):
            target = resolve(p, mod, f.name == "mod.rs")
            if target is None:
                continue
            # The longest known module the path lies in.
            while target and target not in modules:
                target = target[:-1]
            if target and target != mod:
                refs[mod].add(target)
    return modules, refs


def layer_violations() -> int:
    """Prints the daemon's imports that cross its layers the wrong way."""
    modules, refs = module_refs("daemon")
    found = 0
    for mod, targets in sorted(refs.items()):
        if not mod or mod[0] not in DAEMON_LAYERS:
            continue
        for t in sorted(targets):
            if t and t[0] != mod[0] and t[0] in DAEMON_LAYERS and t[0] not in DAEMON_LAYERS[mod[0]]:
                found += 1
                print(f"layer import: daemon::{'::'.join(mod)} → {'::'.join(t)}")
    missing = sorted({m[0] for m in modules if m} - set(DAEMON_LAYERS) - {"lib", "main"})
    for m in missing:
        found += 1
        print(f"layer import: daemon::{m} is in no layer of scripts/module-graph.py")
    return found


def crate_cycles(crate: str, show_edges: bool) -> int:
    modules, refs = module_refs(crate)
    found = 0
    parents = {m[:-1] for m in modules if m} | {()}
    for parent in sorted(parents):
        depth = len(parent)
        children = sorted({m[depth] for m in modules if len(m) > depth and m[:depth] == parent})
        edges: dict[str, set[str]] = defaultdict(set)
        for src_mod, targets in refs.items():
            if len(src_mod) <= depth or src_mod[:depth] != parent:
                continue
            a = src_mod[depth]
            for t in targets:
                if len(t) > depth and t[:depth] == parent and t[depth] != a:
                    edges[a].add(t[depth])
        for comp in sccs(children, edges):
            found += 1
            where = "::".join((crate,) + parent)
            print(f"cycle in {where}: {' ⇄ '.join(comp)}")
            if show_edges:
                for a in comp:
                    print(f"    {a} → {', '.join(sorted(set(edges[a]) & set(comp)))}")
    return found


def long_functions(crates: list[str], top: int) -> None:
    rows = []
    for crate in crates:
        for f in sorted((ROOT / crate / "src").rglob("*.rs")):
            if f.name == "tests.rs":
                continue
            text = strip_tests(f.read_text())
            for m in re.finditer(r"\bfn\s+(\w+)[^;{]*?\{", text, re.S):
                depth, j = 1, m.end()
                while j < len(text) and depth:
                    depth += {"{": 1, "}": -1}.get(text[j], 0)
                    j += 1
                start = text.count("\n", 0, m.start()) + 1
                lines = text.count("\n", m.start(), j) + 1
                rows.append((lines, f"{f.relative_to(ROOT)}:{start}", m.group(1)))
    rows.sort(reverse=True)
    print(f"\nlongest functions (lines, tests aside):")
    for lines, where, name in rows[:top]:
        print(f"  {lines:4d}  {name}  {where}")


def long_files(crates: list[str]) -> None:
    rows = []
    for crate in crates:
        for f in (ROOT / crate / "src").rglob("*.rs"):
            if f.name == "tests.rs":
                continue
            n = strip_tests(f.read_text()).count("\n")
            if n > 700:
                rows.append((n, str(f.relative_to(ROOT))))
    print("\nfiles over 700 lines (tests aside):" + ("" if rows else " none"))
    for n, f in sorted(rows, reverse=True):
        print(f"  {n:5d}  {f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--crates", default="contract,inference,evaluation,daemon,generator")
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--edges", action="store_true", help="print each cycle's edges")
    ap.add_argument("--check", action="store_true", help="exit 1 on a circle or a forbidden layer import")
    args = ap.parse_args()
    crates = [c for c in args.crates.split(",") if (ROOT / c / "src").is_dir()]
    total = sum(crate_cycles(c, args.edges) for c in crates)
    print(f"{total} import cycle(s) in {', '.join(crates)}")
    layers = layer_violations() if "daemon" in crates else 0
    print(f"{layers} forbidden layer import(s) in daemon")
    long_functions(crates, args.top)
    long_files(crates)
    if args.check and (total or layers):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
