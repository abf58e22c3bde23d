#!/usr/bin/python3
"""microsim: the length of every C++ function definition (the project rule: functions at most about 80 lines).

Finds the function definitions (free functions, methods defined in or out of their class, constructors,
destructors, operators, and lambdas bound to a name at namespace or class scope) in the .cpp and .h files
under src/, microgeom/ and apps/ (or the paths given), and reports each one's length in lines, from the
first line of its declaration (a `template <...>` line included) to the line of its closing brace. A
lambda or a local class inside a function counts as part of that function.

The scanner is a brace matcher, not a C++ parser: comments, string literals (raw strings included),
character literals and preprocessor lines are blanked first (a digit separator such as 1'000 is not a
character literal), then the braces are matched by scope: a brace that follows a parameter list opens a
function body; `namespace`, `extern "C"`, `class`, `struct` and `union` open scopes searched further;
anything else (an enum, an initializer, a member's brace initializer in a constructor's list) is skipped.

Usage:
  /usr/bin/python3 scripts/function_lengths.py [--root DIR] [--max N] [--list-all] [--json] [PATH...]
Prints the distribution (<=20, 21-40, 41-80, 81-150, >150 lines), then every function over 80 lines
(file:line name length), longest first. With --max N the exit status is 1 when any function is longer
than N lines (0 otherwise); 2 on bad usage or a file the scanner cannot match (an unbalanced brace).
"""
import argparse
import json
import os
import re
import signal
import sys

DEFAULT_DIRS = ("src", "microgeom", "apps")
SOURCE_SUFFIXES = (".cpp", ".cc", ".cxx", ".h", ".hpp")
BUCKETS = ((20, "<=20"), (40, "21-40"), (80, "41-80"), (150, "81-150"), (None, ">150"))
LONG = 80

RAW_PREFIXES = ("R", "u8R", "uR", "UR", "LR")
SCOPE_KEYWORDS = ("class", "struct", "union")
SKIP_KEYWORDS = ("enum", "typedef", "using", "static_assert", "concept")
NOT_A_NAME = ("decltype", "alignas", "__attribute__", "noexcept", "sizeof", "__declspec", "requires",
              "alignof", "throw")
ACCESS = ("public", "private", "protected")


class ScanError(Exception):
    pass


# ---- step 1: blank comments, literals and preprocessor lines (newlines kept, so lines still count) ------
def blank(text):
    out = []
    i, n = 0, len(text)
    line_start = True  # only whitespace seen since the last newline
    while i < n:
        c = text[i]
        if line_start and c == "#":
            i = blank_directive(text, i, out)
            continue
        if c == "/" and text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
            continue
        if c == "/" and text.startswith("/*", i):
            j = text.find("*/", i + 2)
            if j < 0:
                raise ScanError("unterminated comment")
            out.append(spaces_keeping_newlines(text[i:j + 2]))
            i = j + 2
            continue
        if c == '"':
            i = blank_string(text, i, out)
            line_start = False
            continue
        if c == "'":
            i = blank_char(text, i, out)
            line_start = False
            continue
        if c.isalnum() or c == "_":
            j = word_end(text, i)
            out.append(text[i:j])
            i = j
            line_start = False
            continue
        out.append(c)
        if c == "\n":
            line_start = True
        elif not c.isspace():
            line_start = False
        i += 1
    return "".join(out)


def spaces_keeping_newlines(s):
    return "".join("\n" if ch == "\n" else " " for ch in s)


def blank_directive(text, i, out):
    """A preprocessor line (continued by a trailing backslash) becomes blank."""
    n = len(text)
    j = i
    while j < n:
        k = text.find("\n", j)
        if k < 0:
            k = n
        if k > 0 and text[k - 1] == "\\" and k < n:
            j = k + 1
            continue
        j = k
        break
    out.append(spaces_keeping_newlines(text[i:j]))
    return j


def word_end(text, i):
    """End of an identifier or a number; a number keeps its digit separators (1'000'000) and exponent."""
    n = len(text)
    j = i + 1
    if text[i].isdigit():
        while j < n and (text[j].isalnum() or text[j] in "_.'" or
                         (text[j] in "+-" and text[j - 1] in "eEpP" and not text[i:j].startswith(("0x", "0X"))
                          or text[j] in "+-" and text[j - 1] in "pP")):
            j += 1
        return j
    while j < n and (text[j].isalnum() or text[j] == "_"):
        j += 1
    return j


def previous_word(out):
    s = "".join(out[-3:])
    m = re.search(r"([A-Za-z0-9_]+)$", s)
    return m.group(1) if m else ""


def blank_string(text, i, out):
    if previous_word(out) in RAW_PREFIXES:
        m = re.compile(r'"([^()\\ \n]{0,16})\(').match(text, i)
        if not m:
            raise ScanError("malformed raw string")
        close = ")" + m.group(1) + '"'
        j = text.find(close, m.end())
        if j < 0:
            raise ScanError("unterminated raw string")
        j += len(close)
        out.append('"' + spaces_keeping_newlines(text[i + 1:j - 1]) + '"')
        return j
    return blank_quoted(text, i, out, '"')


def blank_char(text, i, out):
    return blank_quoted(text, i, out, "'")


def blank_quoted(text, i, out, quote):
    n = len(text)
    j = i + 1
    while j < n and text[j] != quote:
        if text[j] == "\\":
            j += 1
        elif text[j] == "\n":
            raise ScanError("unterminated literal")
        j += 1
    if j >= n:
        raise ScanError("unterminated literal")
    out.append(quote + " " * (j - i - 1) + quote)
    return j + 1


# ---- step 2: tokens (identifier, number, literal, punctuator) with their line --------------------------
TOKEN = re.compile(r"""[A-Za-z_][A-Za-z0-9_]*|[0-9][A-Za-z0-9_.']*|"[^"]*"|'[^']*'|::|->|>>|\S""")


def tokenize(cleaned):
    tokens = []
    line = 1
    pos = 0
    for m in TOKEN.finditer(cleaned):
        line += cleaned.count("\n", pos, m.start())
        pos = m.start()
        tokens.append((m.group(0), line))
    return tokens


# ---- step 3: scopes, headers and bodies ------------------------------------------------------------------
def matching(tokens, i, opening, closing):
    """Index of the token closing the bracket opened at i, or None."""
    depth = 0
    for j in range(i, len(tokens)):
        t = tokens[j][0]
        if t == opening:
            depth += 1
        elif t == closing:
            depth -= 1
            if depth == 0:
                return j
    return None


def match_brace(tokens, i):
    """Index of the `}` matching the `{` at i."""
    j = matching(tokens, i, "{", "}")
    if j is None:
        raise ScanError(f"unbalanced '{{' on line {tokens[i][1]}")
    return j


def strip_prefixes(header):
    """Drop `template <...>`, `[[attributes]]` and access labels from the front of a header."""
    h = list(header)
    changed = True
    while changed and h:
        changed = False
        if h[0][0] == "template" and len(h) > 1 and h[1][0] == "<":
            depth, k = 0, 1
            while k < len(h):
                t = h[k][0]
                depth += 1 if t == "<" else -1 if t == ">" else -2 if t == ">>" else 0
                k += 1
                if depth <= 0:
                    break
            h = h[k:]
            changed = True
        elif h[0][0] == "[" and len(h) > 1 and h[1][0] == "[":
            k = 2
            while k + 1 < len(h) and not (h[k][0] == "]" and h[k + 1][0] == "]"):
                k += 1
            h = h[k + 2:]
            changed = True
        elif h[0][0] in ACCESS and len(h) > 1 and h[1][0] == ":":
            h = h[2:]
            changed = True
    return h


def find_parameter_list(h):
    """Index of the `(` opening the parameter list in a header, or None."""
    angle = 0
    k = 0
    while k < len(h):
        t = h[k][0]
        if t == "operator":
            k += 1
            if k < len(h) and h[k][0] == "(":
                k += 2  # operator()
            while k < len(h) and h[k][0] != "(":
                k += 1
            return k if k < len(h) else None
        if t == "<":
            angle += 1
        elif t == ">":
            angle = max(0, angle - 1)
        elif t == ">>":
            angle = max(0, angle - 2)
        elif t == "(" and angle == 0:
            if k > 0 and h[k - 1][0] in NOT_A_NAME:
                k = close_paren(h, k) + 1
                continue
            return k
        elif t == "(":
            k = close_paren(h, k) + 1
            continue
        elif t == "=" and angle == 0:
            return None  # an initializer, not a declaration
        k += 1
    return None


def close_paren(h, k):
    """Index of the `)` matching the `(` at k in a header (its last token if unbalanced)."""
    j = matching(h, k, "(", ")")
    return len(h) - 1 if j is None else j


def function_name(h, paren):
    """The qualified name before the parameter list: ns::Class<T>::method, operator==, ~Class."""
    k = paren - 1
    parts = []
    if any(t == "operator" for t, _ in h[:paren]):
        start = max(i for i, (t, _) in enumerate(h[:paren]) if t == "operator")
        parts = [t for t, _ in h[start:paren]]
        k = start - 1
        name = "operator" + "".join(parts[1:])
    else:
        name = h[k][0] if k >= 0 else "?"
        k -= 1
        if k >= 0 and h[k][0] == "~":
            name = "~" + name
            k -= 1
    while k >= 1 and h[k][0] == "::":
        k -= 1
        if h[k][0] == ">":
            depth = 0
            while k >= 0:
                t = h[k][0]
                depth += 1 if t == ">" else -1 if t == "<" else 0
                k -= 1
                if depth == 0:
                    break
        if k >= 0 and re.match(r"[A-Za-z_]", h[k][0]):
            name = h[k][0] + "::" + name
            k -= 1
        else:
            break
    return name


def in_constructor_list(h, paren):
    """True when the header continues past the parameter list into a member initializer list."""
    end = close_paren(h, paren)
    return any(t == ":" for t, _ in h[end + 1:])


def lambda_binding(h):
    """`name = [captures](...)`: the name bound to a lambda at namespace or class scope, else None."""
    for k, (t, _) in enumerate(h):
        if t == "=" and k + 1 < len(h) and h[k + 1][0] == "[" and k > 0:
            return h[k - 1][0]
    return None


def scan_scope(tokens, i, end, prefix, found):
    """Scan tokens[i:end] (a namespace, class or file scope) and append each function definition found."""
    header = []
    paren_depth = 0
    while i < end:
        t, line = tokens[i]
        if t == "(":
            paren_depth += 1
        elif t == ")":
            paren_depth = max(0, paren_depth - 1)
        if t == ";" and paren_depth == 0:
            header = []
            i += 1
            continue
        if t == "{" and paren_depth > 0:  # a braced expression inside parentheses: part of the header
            j = match_brace(tokens, i)
            header.append(("{}", line))
            i = j + 1
            continue
        if t != "{":
            header.append((t, line))
            i += 1
            continue
        j = match_brace(tokens, i)
        if open_brace(tokens, i, j, header, prefix, found):
            header = []
        else:  # a member's brace initializer in a constructor's list: the header goes on
            header.append(("{}", line))
        i = j + 1


def open_brace(tokens, i, j, header, prefix, found):
    """Classify the block tokens[i..j] by its header. False when it is a member's brace initializer in a
    constructor's list (the header goes on), True otherwise (the block is done with)."""
    h = strip_prefixes(header)
    if not h:
        return True
    first = h[0][0]
    if first == "namespace" or (first == "extern" and len(h) <= 2):
        scan_scope(tokens, i + 1, j, prefix, found)
        return True
    if first in SCOPE_KEYWORDS and "=" not in [t for t, _ in h]:
        names = [t for t, _ in h[1:] if re.match(r"[A-Za-z_]\w*$", t) and t not in ("final", "alignas")]
        scan_scope(tokens, i + 1, j, prefix + (names[0] + "::" if names else ""), found)
        return True
    if first in SKIP_KEYWORDS:
        return True
    bound = lambda_binding(h)
    if bound:
        record(found, prefix + bound, header[0][1], tokens[j][1])
        return True
    paren = find_parameter_list(h)
    if paren is None:  # an initializer: a lambda in it counts as a function of its own
        record_lambdas(tokens, i, j, prefix + initialized_name(h), found)
        return True
    previous = tokens[i - 1][0]
    if in_constructor_list(h, paren) and (re.match(r"\w", previous) or previous == ">"):
        return False
    record(found, prefix + function_name(h, paren), header[0][1], tokens[j][1])
    return True


def initialized_name(h):
    """The variable an initializer belongs to: the last identifier before `=` or the brace."""
    names = [t for t, _ in h if t == "=" or re.match(r"[A-Za-z_]\w*$", t)]
    if "=" in names:
        names = names[:names.index("=")]
    return names[-1] if names else "?"


def record_lambdas(tokens, i, j, name, found):
    """Each lambda in the initializer tokens[i..j] (not inside another), as `name lambda`."""
    k = i + 1
    while k < j:
        if tokens[k][0] == "[" and tokens[k - 1][0] in ("(", ",", "{", "=", "return"):
            body = lambda_body(tokens, k, j)
            if body is not None:
                end = match_brace(tokens, body)
                record(found, name + " lambda", tokens[k][1], tokens[end][1])
                k = end + 1
                continue
        k += 1


def lambda_body(tokens, k, j):
    """Index of the `{` opening the body of a lambda whose capture list opens at k, or None."""
    depth = 0
    while k < j:
        t = tokens[k][0]
        depth += 1 if t in "([" else -1 if t in ")]" else 0
        if t == "{" and depth == 0:
            return k
        if t in (";", ",", "}") and depth == 0:
            return None
        k += 1
    return None


def record(found, name, first_line, last_line):
    found.append({"name": name, "line": first_line, "lines": last_line - first_line + 1})


def scan_file(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    tokens = tokenize(blank(text))
    found = []
    scan_scope(tokens, 0, len(tokens), "", found)
    return found


# ---- step 4: the report --------------------------------------------------------------------------------
def source_files(root, paths):
    for p in paths:
        full = os.path.join(root, p)
        if os.path.isfile(full):
            yield p
            continue
        for dirpath, dirnames, filenames in os.walk(full):
            dirnames.sort()
            for name in sorted(filenames):
                if name.endswith(SOURCE_SUFFIXES):
                    yield os.path.relpath(os.path.join(dirpath, name), root)


def distribution(functions):
    counts = {label: 0 for _, label in BUCKETS}
    for fn in functions:
        for limit, label in BUCKETS:
            if limit is None or fn["lines"] <= limit:
                counts[label] += 1
                break
    return counts


def print_report(functions, list_all):
    counts = distribution(functions)
    print(f"{len(functions)} functions")
    for _, label in BUCKETS:
        print(f"  {label:>7} lines: {counts[label]}")
    shown = functions if list_all else [fn for fn in functions if fn["lines"] > LONG]
    if not list_all:
        print(f"{len(shown)} functions over {LONG} lines:")
    for fn in sorted(shown, key=lambda f: (-f["lines"], f["file"], f["line"])):
        print(f"  {fn['file']}:{fn['line']} {fn['name']} {fn['lines']}")


def main(argv):
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # `| head` ends the listing quietly
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("paths", nargs="*", help="files or folders (default: src microgeom apps)")
    parser.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."),
                        help="repository root (default: this script's parent folder)")
    parser.add_argument("--max", type=int, default=None, help="exit 1 if any function is longer than N lines")
    parser.add_argument("--list-all", action="store_true", help="list every function, not only the long ones")
    parser.add_argument("--json", action="store_true", help="print the functions as JSON")
    args = parser.parse_args(argv)
    if args.max is not None and args.max < 1:
        parser.error(f"--max must be at least 1, got {args.max}")
    root = os.path.abspath(args.root)
    functions = []
    for rel in source_files(root, args.paths or DEFAULT_DIRS):
        try:
            for fn in scan_file(os.path.join(root, rel)):
                fn["file"] = rel
                functions.append(fn)
        except ScanError as e:
            print(f"function_lengths: {rel}: {e}", file=sys.stderr)
            return 2
    if args.json:
        print(json.dumps({"functions": functions, "distribution": distribution(functions)}, indent=1))
    else:
        print_report(functions, args.list_all)
    if args.max is not None:
        over = [fn for fn in functions if fn["lines"] > args.max]
        if over:
            print(f"{len(over)} functions longer than {args.max} lines", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
