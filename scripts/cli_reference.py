#!/usr/bin/env python3
"""Writes docs/reference/cli.md, every command and option of microsim, from the binary's own `--help` (so the
reference cannot drift from the code), or with --check compares the committed file with what the binary says
now: exit 0 when equal, 1 with a diff otherwise (ctest runs the check as `cli_reference`).

  /usr/bin/python3 scripts/cli_reference.py --binary build/microsim [--out docs/reference/cli.md] [--check]

Subcommands are found in each help's "Subcommands" section and documented depth-first. One line of `run`'s
help depends on the build (whether MPI is compiled in); it is written in a build-independent form."""
import argparse
import difflib
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
HEADER = """# Command-line reference

Generated from `microsim --help` and each command's `--help` by `scripts/cli_reference.py`; do not edit: run
`/usr/bin/python3 scripts/cli_reference.py --binary build/microsim` after changing a command's options (the ctest
test `cli_reference` fails while this file differs from the binary's help). The rules every command keeps (exit
codes, outputs, numbers, split runs) are in [command-line.md](command-line.md).
"""
# Lines that differ between builds: (pattern, the build-independent text written instead)
BUILD_DEPENDENT = [
    (re.compile(r"MPI (is not compiled in|is compiled in)[^\n]*?\(docs/[^)]*\)\.?"),
     "MPI: `microsim run --help` of your build says whether MPI is compiled in (without it a run under mpirun "
     "or srun is refused)."),
]


def help_text(binary, words):
    r = subprocess.run([binary, *words, "--help"], capture_output=True, text=True, timeout=60)
    if r.returncode != 0:
        sys.exit(f"cli_reference: `{' '.join(['microsim', *words, '--help'])}` exited {r.returncode}: {r.stderr}")
    # CLI11's usage line names the program as it was invoked: write it as users type it
    text = re.sub(r"^Usage: \S+", "Usage: microsim", r.stdout, flags=re.M)
    for pattern, replacement in BUILD_DEPENDENT:
        text = pattern.sub(replacement, text)
    return "\n".join(line.rstrip() for line in text.strip("\n").split("\n"))


def subcommands(text):
    """The names listed in the help's Subcommands section (CLI11: a 'Subcommands:' line, then '  name  text')."""
    names, inside = [], False
    for line in text.split("\n"):
        if re.match(r"^(Subcommands|SUBCOMMANDS):\s*$", line):
            inside = True
            continue
        if inside:
            m = re.match(r"^  (\S+)", line)
            if m:
                names.append(m.group(1))
            elif line.strip() == "" or not line.startswith(" "):
                inside = False
    return names


def reference(binary):
    parts, order = [HEADER], []

    def visit(words):
        text = help_text(binary, words)
        order.append((words, text))
        for name in subcommands(text):
            visit([*words, name])

    visit([])
    parts.append("Commands: " + ", ".join(f"`{' '.join(['microsim', *w])}`" for w, _ in order[1:]) + ".\n")
    for words, text in order:
        level = "#" * min(2 + max(len(words) - 1, 0), 4)
        parts.append(f"{level} `{' '.join(['microsim', *words])}`\n\n```text\n{text}\n```\n")
    return "\n".join(parts)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--binary", required=True)
    p.add_argument("--out", default=str(ROOT / "docs/reference/cli.md"))
    p.add_argument("--check", action="store_true", help="compare with --out instead of writing it")
    a = p.parse_args()
    new = reference(a.binary)
    out = pathlib.Path(a.out)
    if not a.check:
        out.write_text(new)
        print(f"wrote {out}")
        return 0
    old = out.read_text() if out.exists() else ""
    if old == new:
        print(f"{out} matches the binary's help")
        return 0
    sys.stdout.writelines(difflib.unified_diff(old.splitlines(True), new.splitlines(True), str(out), "binary --help"))
    print(f"\n{out} differs from the binary's help: regenerate it with "
          f"/usr/bin/python3 scripts/cli_reference.py --binary {a.binary}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
