#!/usr/bin/env python3
"""The commands of the user-facing docs run as written: every fenced ```sh, ```bash or ```console block of
README.md and docs/guide/*.md is run against the built binary in a scratch folder, command by command, and must
exit as the doc says (0, or the N of a trailing comment that says "exit N"). A block that cannot run in a test
(setup, the hour-long jobs, a cluster) is skipped only when the doc says so, on the line before it:
`<!-- not-run: the reason -->`; the test lists every skip with its reason.

  /usr/bin/python3 tests/docs/test_doc_commands.py --binary build/microsim --python-path build/python \\
      --scratch build/docs-commands [--only README.md]

`microsim` and `build/microsim` are the built binary; Python commands name Debian's /usr/bin/python3 (with
numpy; a bare `python3` is a failure: the user's PATH may hold one without numpy), run with the built module on
PYTHONPATH (`build/python` too). Each page runs in its
own folder holding a copy of examples/; the scratch folder is removed at the end, pass or fail. Exit 0 when
every command exits as documented, 1 otherwise (each failure shown with its output), 2 for a malformed marker.
A self-test runs first: a failing command, a wrong exit code and a bare python3 must be caught (the negative
control)."""
import argparse
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
OPEN = re.compile(r"^```(sh|bash|console)\s*$")
NOT_RUN = re.compile(r"^<!--\s*not-run:(.*?)-->\s*$")
EXPECTED_EXIT = re.compile(r"#.*\bexit (\d+)\b")
TIMEOUT = 300  # seconds per command: far above what any documented command takes


class MarkerError(Exception):
    pass


def blocks(text, name):
    """(first line number, language, body lines, not-run reason or None) of each shell block of a page."""
    lines = text.split("\n")
    out, i = [], 0
    while i < len(lines):
        m = NOT_RUN.match(lines[i].strip())
        if m:
            reason = m.group(1).strip()
            if not reason:
                raise MarkerError(f"{name}:{i + 1}: a not-run marker must give its reason")
            if i + 1 >= len(lines) or not OPEN.match(lines[i + 1]):
                raise MarkerError(f"{name}:{i + 1}: a not-run marker must stand on the line before a ```sh block")
        o = OPEN.match(lines[i])
        if o:
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            prev = NOT_RUN.match(lines[i - 1].strip()) if i > 0 else None
            out.append((i + 1, o.group(1), lines[i + 1:j], prev.group(1).strip() if prev else None))
            i = j
        elif lines[i].startswith("```"):  # another language's block: skip to its end
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                i += 1
        i += 1
    return out


def commands(language, body):
    """The commands of a block, continuation lines joined; a console block's commands are its `$ ` lines."""
    out, current = [], None
    for line in body:
        if language == "console" and current is None:
            if not line.startswith("$ "):
                continue  # output shown in the doc
            line = line[2:]
        if current is not None:
            current += "\n" + line
        else:
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            current = line
        if not current.endswith("\\"):
            out.append(current)
            current = None
    if current is not None:
        out.append(current)
    return out


def expected_exit(command):
    m = EXPECTED_EXIT.search(command.split("\n")[-1])
    return int(m.group(1)) if m else 0


# A command that runs a bare `python3` (after any VAR=value): it would take the first python3 on the user's PATH,
# which may lack numpy (a pyenv shim, say); the pages name Debian's /usr/bin/python3.
BARE_PYTHON = re.compile(r"(?:^|[;&|(]\s*)(?:\w+=\S*\s+)*python3(?:\s|$)", re.M)


def prepare(folder, binary, python_path):
    """A page's folder: examples/ copied, bin/ with microsim, build/microsim, the example BSDF plugins
    built beside it (build/microsim_plugin_*.so) and build/python."""
    folder.mkdir(parents=True)
    shutil.copytree(ROOT / "examples", folder / "examples", ignore=shutil.ignore_patterns("__pycache__"))
    (folder / "bin").mkdir()
    (folder / "build").mkdir()
    if binary:
        (folder / "bin/microsim").symlink_to(pathlib.Path(binary).resolve())
        (folder / "build/microsim").symlink_to(pathlib.Path(binary).resolve())
        for plugin in pathlib.Path(binary).resolve().parent.glob("microsim_plugin_*.so"):
            (folder / "build" / plugin.name).symlink_to(plugin)
    if python_path:
        (folder / "build/python").symlink_to(pathlib.Path(python_path).resolve())


def run_page(name, text, folder, binary, python_path, report, quiet):
    prepare(folder, binary, python_path)
    env = dict(os.environ, PATH=f"{folder / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
               PYTHONDONTWRITEBYTECODE="1")
    if python_path:
        env["PYTHONPATH"] = str(pathlib.Path(python_path).resolve())
    failures = 0
    for line, language, body, reason in blocks(text, name):
        cmds = commands(language, body)
        if reason is not None:
            report["skipped"].append((f"{name}:{line}", len(cmds), reason))
            continue
        for command in cmds:
            if BARE_PYTHON.search(command):
                failures += 1
                if not quiet:
                    print(f"FAIL {name}:{line}: runs a bare python3 (write /usr/bin/python3):\n  $ {command}\n")
                continue
            want = expected_exit(command)
            start = time.monotonic()
            try:
                r = subprocess.run(["bash", "-o", "pipefail", "-c", command], cwd=folder, env=env, timeout=TIMEOUT,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace")
                code, output = r.returncode, r.stdout
            except subprocess.TimeoutExpired as e:
                code, output = "timeout", (e.stdout or b"").decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
            seconds = time.monotonic() - start
            report["ran"].append((f"{name}:{line}", command, seconds))
            if code != want:
                failures += 1
                tail = "\n".join(output.rstrip().split("\n")[-25:])
                if not quiet:
                    print(f"FAIL {name}:{line}: exit {code}, the doc says {want} ({seconds:.1f} s):\n  $ {command}\n{tail}\n")
    return failures


def run(pages, binary, python_path, scratch, quiet=False):
    report = {"ran": [], "skipped": []}
    failures = 0
    scratch = pathlib.Path(scratch).resolve()
    if scratch.exists():
        shutil.rmtree(scratch)
    try:
        for name, text in pages:
            folder = scratch / re.sub(r"[^A-Za-z0-9_.-]", "_", name)
            failures += run_page(name, text, folder, binary, python_path, report, quiet)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return failures, report


def self_test():
    page = ("text\n```sh\ntrue\necho a \\\n  b\nfalse   # rejected: exit 1\n```\n"
            "<!-- not-run: a cluster -->\n```bash\nfalse\n```\n```console\n$ true\noutput line\n```\n"
            "```python\nfalse\n```\n")
    with tempfile.TemporaryDirectory() as tmp:
        failures, report = run([("page.md", page)], None, None, pathlib.Path(tmp) / "s", quiet=True)
        assert failures == 0 and len(report["ran"]) == 4, (failures, report)
        assert report["skipped"] == [("page.md:9", 1, "a cluster")], report["skipped"]
        bad = "```sh\nfalse\ntrue   # exit 1\n```\n"
        failures, _ = run([("bad.md", bad)], None, None, pathlib.Path(tmp) / "s", quiet=True)
        assert failures == 2, failures  # a failing command and a wrong documented exit code are both caught
        bare = "```sh\npython3 -c 1\nPYTHONPATH=x python3 -c 1\ntrue && python3 -c 1\n/usr/bin/python3 -c 1\n```\n"
        failures, report = run([("bare.md", bare)], None, None, pathlib.Path(tmp) / "s", quiet=True)
        assert failures == 3 and len(report["ran"]) == 1, (failures, report)  # only /usr/bin/python3 runs
        assert not (pathlib.Path(tmp) / "s").exists()
    for malformed in ("<!-- not-run: -->\n```sh\ntrue\n```\n", "<!-- not-run: why -->\ntext\n"):
        try:
            blocks(malformed, "m.md")
        except MarkerError:
            continue
        raise AssertionError(f"malformed marker accepted: {malformed!r}")
    print("self-test: a failing command, a wrong exit code, a bare python3 and malformed markers are caught")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--binary", required=True)
    p.add_argument("--python-path", help="the folder of the built Python module (build/python)")
    p.add_argument("--scratch", required=True, help="a folder for the commands' files, removed at the end")
    p.add_argument("--only", action="append", help="a page to run (path from the repository root); repeatable")
    a = p.parse_args()
    self_test()
    names = a.only or ["README.md", *sorted(str(x.relative_to(ROOT)) for x in (ROOT / "docs/guide").glob("*.md"))]
    try:
        pages = [(n, (ROOT / n).read_text()) for n in names]
        for n, t in pages:
            blocks(t, n)
    except MarkerError as e:
        print(e)
        return 2
    start = time.monotonic()
    failures, report = run(pages, a.binary, a.python_path, a.scratch)
    slow = sorted(report["ran"], key=lambda r: -r[2])[:5]
    print(f"ran {len(report['ran'])} commands from {len(pages)} pages in {time.monotonic() - start:.0f} s; "
          f"slowest: " + "; ".join(f"{s:.1f} s {c.split(chr(10))[0][:70]}" for _, c, s in slow))
    skipped = sum(n for _, n, _ in report["skipped"])
    print(f"skipped {skipped} commands in {len(report['skipped'])} blocks marked not-run:")
    for where, n, reason in report["skipped"]:
        print(f"  {where}: {n} command(s): {reason}")
    print(f"{failures} command(s) did not exit as documented" if failures else "every command exited as documented")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
