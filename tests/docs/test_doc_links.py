#!/usr/bin/env python3
"""Every relative link of README.md and docs/**/*.md points to a file or folder that exists (anchors are not
checked; http(s) and mailto links are left alone). Exit 0 when all resolve, 1 naming each broken link.
A self-test first shows that a broken link is caught (the negative control)."""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
# [text](target) and ![alt](target); a target ends at the first space or closing parenthesis
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def links(text):
    """(line number, target) of every link outside fenced code blocks and inline code spans."""
    inside = False
    for number, line in enumerate(text.split("\n"), 1):
        if FENCE.match(line):
            inside = not inside
            continue
        if inside:
            continue
        for m in LINK.finditer(re.sub(r"`[^`]*`", "", line)):
            yield number, m.group(1)


def broken(path, text):
    out = []
    for number, target in links(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # a URL (http:, mailto:) or an anchor in the same page
        file = target.split("#", 1)[0]
        if not (path.parent / file).exists():
            out.append(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{number}: {target}")
    return out


def self_test(tmp):
    page = tmp / "page.md"
    page.write_text("[ok](page.md) [anchor](#x) [web](https://example.org) `[code](nowhere.md)`\n"
                    "[gone](missing.md#part) ![img](figures/none.svg)\n```\n[in a block](nowhere.md)\n```\n")
    found = broken(page, page.read_text())
    assert found == [f"{page}:2: missing.md#part", f"{page}:2: figures/none.svg"], found


def main():
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        self_test(pathlib.Path(tmp))
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    bad = [b for page in pages for b in broken(page, page.read_text())]
    for b in bad:
        print("broken link:", b)
    print(f"{len(pages)} pages, {sum(1 for p in pages for _ in links(p.read_text()))} links, {len(bad)} broken")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
