#!/usr/bin/env python3
"""Unused-dependency check of the hygiene gate (issue 18), in the manner of cargo-machete: a dependency whose
crate name appears nowhere in its package's Rust sources is reported. A dependency kept only to switch on a
feature is listed under `[package.metadata.ulab] feature-only = [...]` in that package's Cargo.toml.

Usage: python3 scripts/unused_deps.py  (from the repository root; exit 1 lists the unused ones)."""
import glob
import os
import re
import sys
import tomllib

SECTIONS = ("dependencies", "dev-dependencies", "build-dependencies")


def unused(manifest: str) -> list[str]:
    root = os.path.dirname(manifest)
    with open(manifest, "rb") as f:
        t = tomllib.load(f)
    allowed = set(t.get("package", {}).get("metadata", {}).get("ulab", {}).get("feature-only", []))
    sources = [p for p in glob.glob(os.path.join(root, "**", "*.rs"), recursive=True) if "/target/" not in p]
    text = "".join(open(p, encoding="utf-8").read() for p in sources)
    found = []
    for section in SECTIONS:
        for name in t.get(section, {}):
            ident = name.replace("-", "_")
            if name not in allowed and not re.search(r"\b" + re.escape(ident) + r"\b", text):
                found.append(f"{manifest}: [{section}] {name}")
    return found


def main() -> int:
    manifests = sorted(glob.glob("crates/*/Cargo.toml")) + ["fuzz/Cargo.toml"]
    problems = [p for m in manifests for p in unused(m)]
    for p in problems:
        print(f"unused dependency: {p}")
    print(f"unused_deps.py: {len(manifests)} manifests, {len(problems)} unused dependencies")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
