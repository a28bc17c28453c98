#!/usr/bin/env python3
"""Import-cycle check of the hygiene gate (issue 18): within each crate, the top-level modules (a file `src/x.rs` or
a directory `src/x/`) form a graph by their `crate::y` references in code (comments and doc links excluded); any
cycle between two top-level modules is reported. Submodules of one module may use their parent freely.

Usage: python3 scripts/module_cycles.py  (from the repository root; exit 1 lists the cycles)."""
import glob
import os
import re
import sys


def graph(src: str) -> dict[str, set[str]]:
    mods: dict[str, set[str]] = {}
    for path in glob.glob(os.path.join(src, "**", "*.rs"), recursive=True):
        top = os.path.relpath(path, src)[:-3].split(os.sep)[0]
        if top in ("lib", "main"):
            continue
        with open(path, encoding="utf-8") as f:
            code = "\n".join(line for line in f if not line.strip().startswith("//"))
        mods.setdefault(top, set()).update(d for d in re.findall(r"crate::(\w+)", code) if d != top)
    return {m: {d for d in deps if d in mods} for m, deps in mods.items()}


def cycles(mods: dict[str, set[str]]) -> list[tuple[str, str]]:
    def reach(a: str) -> set[str]:
        seen, stack = set(), [a]
        while stack:
            for y in mods.get(stack.pop(), ()):
                if y not in seen:
                    seen.add(y)
                    stack.append(y)
        return seen

    # Every edge that lies on a cycle.
    return sorted((a, b) for a in mods for b in mods[a] if a in reach(b))


def main() -> int:
    found = []
    for src in sorted(glob.glob("crates/*/src")):
        mods = graph(src)
        for a, b in cycles(mods):
            found.append(f"{os.path.dirname(src)}: {a} -> {b} lies on a cycle")
    for f in found:
        print(f"import cycle: {f}")
    print(f"module_cycles.py: {len(glob.glob('crates/*/src'))} crates, {len(found)} cycles")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
