#!/usr/bin/env python3
"""No function in src/ over 120 lines without a reason (issue #44).

A function may be longer when its doc comment says why, in the form the
code base uses: "Long (~N lines) on purpose: ...". Run from the repository
root (CI does, beside scripts/import_graph.py); exit 1 lists the others.

Functions are found by their `fn` line and the closing brace at the same
indentation (rustfmt's layout); a declaration without a body is skipped.
"""
import pathlib
import re
import sys

LIMIT = 120
FN = re.compile(r"^(\s*)(pub(\([^)]*\))? )?(const )?(unsafe )?(async )?fn (\w+)")


def long_functions(path):
    lines = path.read_text().split("\n")
    for i, line in enumerate(lines):
        m = FN.match(line)
        if not m or line.rstrip().endswith(";"):
            continue
        indent = m.group(1)
        end = i + 1
        while end < len(lines) and not re.match(re.escape(indent) + r"\}($|[ ;)])", lines[end]):
            end += 1
        n = end - i + 1
        if n <= LIMIT:
            continue
        doc = []
        k = i - 1
        while k >= 0 and lines[k].strip().startswith(("///", "#[")):
            doc.append(lines[k])
            k -= 1
        reason = any(re.search(r"Long \(~\d+ lines\) on purpose", d) for d in doc)
        yield n, i + 1, m.group(7), reason


def main():
    bad = []
    total = 0
    for path in sorted(pathlib.Path("src").rglob("*.rs")):
        for n, line, name, reason in long_functions(path):
            total += 1
            if not reason:
                bad.append(f"{path}:{line}: fn {name} is {n} lines")
    if bad:
        print("functions over %d lines without 'Long (~N lines) on purpose: ...'" % LIMIT
              + " in their doc comment:", file=sys.stderr)
        for b in bad:
            print("  " + b, file=sys.stderr)
        return 1
    print(f"{total} functions over {LIMIT} lines, each with its reason")
    return 0


if __name__ == "__main__":
    sys.exit(main())
