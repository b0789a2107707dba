#!/usr/bin/env python3
"""Lists top-level function bodies longer than a limit (default 80 lines, the project's rule:
tests/long_functions_test.sh).

usage: long-functions.py [--max N] DIR...   (exit 1 when any is found)
A function body is a '{' outside any other braces but those of namespaces and
extern "C", after a ')' (with const/noexcept/override/an initializer list
between); comments, strings and characters are ignored. Classes, enums and
brace initializers are not functions.
"""
import re
import sys
from pathlib import Path


def strip(text):
    """Comments, string and character literals blanked (newlines kept)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i)); i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif c == 'R' and text.startswith('R"', i) and (i == 0 or not (text[i-1].isalnum() or text[i-1] == '_')):
            k = text.find("(", i)
            delim = ")" + text[i + 2:k] + '"'
            j = text.find(delim, k)
            j = n if j < 0 else j + len(delim)
            out.append(re.sub(r"[^\n]", " ", text[i:j])); i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(" " * (min(j + 1, n) - i)); i = j + 1
        else:
            out.append(c); i += 1
    return "".join(out)


def functions(path):
    text = strip(path.read_text(errors="replace"))
    stack = []  # 'ns' (transparent) or 'other'
    results = []
    i = 0
    while i < len(text):
        c = text[i]
        if c == "{":
            head = text[max(0, text.rfind(";", 0, i), text.rfind("}", 0, i), text.rfind("{", 0, i)) + 1:i]
            h = " ".join(head.split())
            if re.search(r"\bnamespace\b[\w:\s]*$", h) or re.search(r'extern\s*$', h) or h.endswith('extern'):
                stack.append("ns")
            elif all(s == "ns" for s in stack) and re.search(r"\)\s*(const|noexcept|override|final|mutable|->[^{]*|:[^{;]*|\s)*$", h) \
                    and not re.search(r"\b(class|struct|enum|union)\b", h) and not re.search(r"=\s*$", h):
                start = i
                depth, j = 0, i
                while j < len(text):
                    if text[j] == "{": depth += 1
                    elif text[j] == "}":
                        depth -= 1
                        if depth == 0: break
                    j += 1
                line0 = text.count("\n", 0, start) + 1
                line1 = text.count("\n", 0, j) + 1
                name = re.sub(r"\s*\(.*", "", h.split("(")[0]).split()[-1] if "(" in h else h
                results.append((line1 - line0 + 1, line0, name))
                i = j + 1
                continue
            else:
                stack.append("other")
        elif c == "}":
            if stack: stack.pop()
        i += 1
    return results


def main(argv):
    limit = 80
    if argv[:1] == ["--max"]:
        limit, argv = int(argv[1]), argv[2:]
    found = 0
    for d in argv or ["."]:
        for p in sorted(Path(d).rglob("*")):
            if p.suffix not in (".cpp", ".h", ".cc") or "build" in p.parts:
                continue
            for lines, line, name in functions(p):
                if lines > limit:
                    print(f"{p}:{line}: {name}: {lines} lines")
                    found += 1
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
