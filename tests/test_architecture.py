#!/usr/bin/env python3
"""The module graph of docs/architecture.md, checked: every #include "module/..." of a module's files
names a module it may use. Exit 0 when the tree keeps the graph, 1 with the offending lines otherwise.
A self-test first shows the check rejects a forbidden include (the negative control)."""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
# module -> (folder, modules it may include, besides itself)
GRAPH = {
    "core": ("src/core", set()),
    "microgeom": ("microgeom", {"core"}),
    "microfacet": ("src/microfacet", {"core"}),
    "stats": ("src/stats", {"core", "microgeom", "microfacet"}),
    "trace": ("src/trace", {"core", "microgeom", "microfacet", "stats"}),
    "validate": ("src/validate", {"core", "microgeom", "microfacet", "stats", "trace"}),
    "scatter": ("src/scatter", {"core", "microgeom", "microfacet", "stats", "trace"}),
    "measure": ("src/measure", {"core", "microgeom", "microfacet", "stats", "trace", "validate", "scatter"}),
    "experiment": ("src/experiment",
                   {"core", "microgeom", "microfacet", "stats", "trace", "validate", "scatter", "measure"}),
    # the Python module (pybind11): a front end beside apps/, over the same library
    "python": ("src/python", {"core", "microgeom", "microfacet", "stats", "trace", "validate", "scatter", "measure",
                              "experiment"}),
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([a-z_]+)/[^"]+"', re.M)


def violations(module, text, path):
    allowed = GRAPH[module][1] | {module}
    out = []
    for m in INCLUDE.finditer(text):
        used = m.group(1)
        if used in GRAPH and used not in allowed:
            line = text.count("\n", 0, m.start()) + 1
            out.append(f"{path}:{line}: module {module} includes {used}/ (allowed: {', '.join(sorted(allowed))})")
    return out


def main():
    # Negative control: the check must reject core including the oracle.
    if not violations("core", '#include "trace/embree.h"\n', "self-test"):
        print("self-test failed: a forbidden include was accepted")
        return 1
    found, files = [], 0
    for module, (folder, _) in GRAPH.items():
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix in (".h", ".cpp"):
                files += 1
                found += violations(module, path.read_text(errors="replace"), path.relative_to(ROOT))
    for v in found:
        print(v)
    print(f"{files} files of {len(GRAPH)} modules checked: {len(found)} forbidden includes")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
