#!/usr/bin/python3
"""The include structure of stf's libraries, checked: every library shows a face and keeps its
inside, and no include arrow runs back up inside a folder.

A library is a folder with a public face, include/stf/<library>/, included as
"stf/<library>/NAME.h"; the headers beside its sources are its inside. Checked over ROOT:
  1. no file outside a library includes one of its inside headers (tests/ are exempt: they test
     insides);
  2. no include names a public header without its folder ("grid.h" for "stf/core/grid.h");
  3. no cycle among the modules of one library or folder (a header and its source are one
     module): every file includes only its own level or below.
One line per breach and exit 1; exit 0 when there is none; exit 2 when ROOT holds no library.

usage: structure.py ROOT
"""
import os
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
SOURCES = (".h", ".hpp", ".cpp", ".cc")
SKIP = {"build", ".git", "tests", "out"}


def source_files(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP and not d.startswith("build"))
        for name in sorted(files):
            if name.endswith(SOURCES):
                yield os.path.relpath(os.path.join(folder, name), root)


def includes(root, path):
    with open(os.path.join(root, path), encoding="utf-8", errors="replace") as f:
        return [m.group(1) for m in map(INCLUDE.match, f) if m]


def libraries(root):
    """{library: (its public header names, its inside header names)}."""
    libs = {}
    for name in sorted(os.listdir(root)):
        face = os.path.join(root, name, "include", "stf", name)
        if name in SKIP or not os.path.isdir(face):
            continue
        public = {h for h in os.listdir(face) if h.endswith(SOURCES)}
        inside = {h for h in os.listdir(os.path.join(root, name)) if h.endswith((".h", ".hpp"))}
        libs[name] = (public, inside)
    return libs


def top_folder(path):
    return path.split(os.sep)[0]


def module_of(path, libs):
    """(folder, module name): a library's face and inside are one folder; the name drops the
    extension, so a header and its source are one module."""
    parts = path.split(os.sep)
    folder = parts[0] if parts[0] in libs else os.path.dirname(path)
    return folder, os.path.splitext(parts[-1])[0]


def target_of(path, included, libs, root):
    """The module an include line names, when it is one of the same folder's or library's."""
    parts = included.split("/")
    if len(parts) == 3 and parts[0] == "stf" and parts[1] in libs:
        return parts[1], os.path.splitext(parts[2])[0]
    here = os.path.dirname(path)
    if "/" not in included and os.path.exists(os.path.join(root, here, included)):
        return module_of(os.path.join(here, included), libs)
    return None


def face_breaches(root, files, libs):
    inside_of = {h: lib for lib, (_, inside) in libs.items() for h in inside}
    public_of = {h: lib for lib, (public, _) in libs.items() for h in public}
    for path in files:
        for included in includes(root, path):
            name = included.split("/")[-1]
            if included.startswith("stf/") or os.path.exists(os.path.join(root, os.path.dirname(path), included)):
                continue  # through a face, or a file of the includer's own folder
            if name in inside_of and top_folder(path) != inside_of[name]:
                lib = inside_of[name]
                yield f"{path}: includes {included}, the inside of {lib} (use its face, include/stf/{lib}/)"
            elif name in public_of:
                yield f'{path}: includes "{included}" without its folder: "stf/{public_of[name]}/{name}"'


def cycles(edges):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def cycle_breaches(root, files, libs):
    edges = {}
    for path in files:
        source = module_of(path, libs)
        for included in includes(root, path):
            target = target_of(path, included, libs, root)
            if target and target != source and target[0] == source[0]:
                edges.setdefault(source, set()).add(target)
    for component in cycles(edges):
        folder = component[0][0]
        yield f"{folder}: include cycle among " + ", ".join(name for _, name in component)


def main(argv):
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    root = argv[1]
    libs = libraries(root)
    if not libs:
        print(f"structure.py: {root} holds no library (no folder with include/stf/<name>/)", file=sys.stderr)
        return 2
    files = list(source_files(root))
    breaches = list(face_breaches(root, files, libs)) + list(cycle_breaches(root, files, libs))
    for line in breaches:
        print(line)
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
