#!/usr/bin/python3
"""The code's size limits (docs/design.md, "Code"), checked: no source file over --max-file lines,
no function over --max-function lines (signature to closing brace) or with more than
--max-params parameters. Prints one line per breach and exits 1 if there is one; with --list,
every function with its lines and parameters.

Usage: tools/code_limits.py [--max-file 400] [--max-function 60] [--max-params 6] [--allow NAME]...
                            [--list] DIR...
--allow NAME exempts the function NAME (as printed, e.g. ShellSampler::jump) from the parameter
limit: for a published signature that callers outside the project rely on.

A small scanner, not a compiler: comments, strings and preprocessor lines are blanked, then a
brace opens a function body where the text before it (since the last ';', '{' or '}') ends in
a parameter list, its qualifiers or a constructor's initialisers, at namespace or class scope.
Lambdas and local classes count towards the function they are in.
"""
import argparse
import os
import re
import sys

SOURCE = (".h", ".cpp")
TYPE_KEYWORDS = re.compile(r"\b(class|struct|union|enum)\b")
ACCESS = re.compile(r"^\s*(public|private|protected)\s*:(?!:)")
FUNCTION_TAIL = re.compile(r"\)\s*(const\b|override\b|final\b|noexcept\b|mutable\b|&|\s)*$")


def blank_out(text):
    """The text with comments, string and char literals and preprocessor lines replaced by
    spaces (newlines kept, so offsets map to the same lines)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i) or (c == "#" and (i == 0 or text[i - 1] == "\n" or text[:i].rstrip(" \t").endswith("\n"))):
            j = text.find("\n", i)
            j = n if j < 0 else j
            while c == "#" and j > 0 and text[j - 1] == "\\":  # continued macro lines
                j = text.find("\n", j + 1)
                j = n if j < 0 else j
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "'" and i > 0 and text[i - 1].isalnum():  # a digit separator (1'000'000)
            out.append(c)
            i += 1
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + re.sub(r"[^\n]", " ", text[i + 1:min(j, n - 1)]) + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def split_initialisers(head):
    """The declaration without a constructor's initialiser list (a single ':' after the ')')."""
    depth = 0
    for k, c in enumerate(head):
        depth += c in "(<[" and 1 or (-1 if c in ")>]" else 0)
        if c == ":" and depth == 0 and head[k - 1:k] != ":" and head[k + 1:k + 2] != ":" and ")" in head[:k]:
            return head[:k]
    return head


def parameter_count(head):
    """Parameters of the last top-level parenthesised group of a declaration."""
    head = split_initialisers(head).split("->")[0].rstrip()
    end = head.rfind(")")
    depth, start = 0, -1
    for k in range(end, -1, -1):
        depth += {")": 1, "(": -1}.get(head[k], 0)
        if depth == 0:
            start = k
            break
    inner = head[start + 1:end].strip()
    if not inner or inner == "void":
        return 0
    depth, commas = 0, 0
    for c in inner:
        depth += {"(": 1, "<": 1, "[": 1, "{": 1, ")": -1, ">": -1, "]": -1, "}": -1}.get(c, 0)
        commas += c == "," and depth == 0
    return commas + 1


def is_function_head(head):
    head = split_initialisers(head).split("->")[0].strip() if "(" in head else head
    declarator = re.sub(r"\boperator\s*[^\s(]*", "operator", head.split("(")[0])  # operator== is no assignment
    return bool(head) and "=" not in declarator and FUNCTION_TAIL.search(head) is not None


def brace_kind(head, inside_fn):
    """What a '{' opens, from the text before it: a namespace, a member's braces in a
    constructor's initialiser list, a function body, a type, or anything else."""
    if re.search(r"\b(namespace|extern)\b", head):
        return "ns"
    if inside_fn:
        return "other"
    if split_initialisers(head) != head and not re.search(r"[)}]\s*$", head):  # the body follows a ')' or '}'
        return "init"
    if is_function_head(head.strip()):
        return "fn"
    return "type" if TYPE_KEYWORDS.search(head) else "other"


def functions(path):
    """(name, first line, last line, parameters) of every function defined in the file."""
    text = blank_out(open(path, encoding="utf-8").read())
    found, scopes, last_stop = [], [], 0  # scopes: (kind,) or ("fn", first line, parameters, head)
    for k, c in enumerate(text):
        if c == ";":
            last_stop = k + 1
        elif c == "{":
            head = text[last_stop:k]
            kind = brace_kind(head, any(s[0] == "fn" for s in scopes))
            if kind == "fn":
                signature = ACCESS.sub(lambda m: " " * len(m.group(0)), head)  # from after public: etc.
                first = text.count("\n", 0, last_stop + len(signature) - len(signature.lstrip())) + 1
                scopes.append(("fn", first, parameter_count(head.strip()), signature.strip()))
            else:
                scopes.append((kind,))
            if kind != "init":  # a member's braces are part of the constructor's head
                last_stop = k + 1
        elif c == "}" and scopes:
            s = scopes.pop()
            if s[0] == "fn":
                name = re.sub(r"\s+", " ", split_initialisers(s[3]).split("(")[0]).split(" ")[-1]
                found.append((name, s[1], text.count("\n", 0, k) + 1, s[2]))
            if s[0] != "init":
                last_stop = k + 1
    return found


def breaches(path, a):
    """The lines reporting where one file breaks the limits."""
    found = []
    text = open(path, encoding="utf-8").read()
    lines = text.count("\n") + (not text.endswith("\n") and text != "")
    if lines > a.max_file:
        found.append(f"{path}: {lines} lines (limit {a.max_file})")
    for name, first, last, params in functions(path):
        length = last - first + 1
        if a.list:
            print(f"{path}:{first}: {name} {length} lines, {params} parameters")
        if length > a.max_function or (params > a.max_params and name not in a.allow):
            found.append(f"{path}:{first}: {name}: {length} lines, {params} parameters "
                         f"(limits {a.max_function} and {a.max_params})")
    return found


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--max-file", type=int, default=400)
    ap.add_argument("--max-function", type=int, default=60)
    ap.add_argument("--max-params", type=int, default=6)
    ap.add_argument("--allow", action="append", default=[], help="a function exempt from --max-params")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args()
    for d in a.dirs:
        if not os.path.isdir(d) or not any(f.endswith(SOURCE) for _, _, files in os.walk(d) for f in files):
            print(f"code_limits: {d}: no folder of C++ sources", file=sys.stderr)
            return 2
    paths = sorted(os.path.join(root, f) for d in a.dirs for root, _, files in os.walk(d) for f in files
                   if f.endswith(SOURCE))
    found = [line for path in paths for line in breaches(path, a)]
    for line in found:
        print(line)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
