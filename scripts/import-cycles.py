#!/usr/bin/env python3
"""No circle of imports among the files of the physics crate (issue 37).

    python3 scripts/import-cycles.py [SRC_DIR]      # default fmu-src/physics/src

Reads the crate's module tree from its `mod` declarations (from lib.rs down, `#[path]`
honoured) and, in each file, every path that starts with `crate::` or `super::` (in `use`
lines and in code; comments and string literals stripped), a glob `use super::*` included,
and in a module's own file the paths that start with one of its child modules. A path is
resolved module by module as far as the tree goes: `use crate::components::cylinder::X`
depends on components/cylinder.rs, `use super::*` on the parent's file, `crate::Params` on
lib.rs (a re-export is a dependency on the file that re-exports). A `mod child;` makes the
parent depend on the child's file.

Test modules (`#[cfg(test)] mod tests`, inline or in a file of their own) are nodes of their
own: their parent declares them but does not use them, and a test may import from any
module, so they depend on others but nothing depends on them but other tests.

Prints each cycle between files (strongly connected component, with one circle through it)
and exits 1 if there is any; prints the layering (files in dependency order) with -v.
Pure Python standard library.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SEGMENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|\*")


def strip(src):
    """Source without comments, string and char literals (their lengths kept roughly)."""
    out, i, n = [], 0, len(src)
    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            i = n if j < 0 else j
        elif src.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if src.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif src.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif c == '"' or (c == "r" and re.match(r'r#*"', src[i:])):
            start = i
            m = re.match(r'r(#*)"', src[i:])
            if m:
                end = '"' + m.group(1)
                j = src.find(end, i + len(m.group(0)))
                i = n if j < 0 else j + len(end)
            else:
                i += 1
                while i < n and src[i] != '"':
                    i += 2 if src[i] == "\\" else 1
                i += 1
            literal = src[start:i]
            # `#[path = "..."]` keeps its file name; every other literal is emptied.
            out.append(literal if re.search(r"path\s*=\s*$", "".join(out[-8:])) else '""')
        elif c == "'" and re.match(r"'(\\.|[^\\'])'", src[i:]):
            i += len(re.match(r"'(\\.|[^\\'])'", src[i:]).group(0))
            out.append("' '")
        else:
            out.append(c)
            i += 1
    return "".join(out)


class Module:
    def __init__(self, path, file, parent, test):
        self.path, self.file, self.parent, self.test = path, file, parent, test
        self.children = {}  # name -> Module
        self.code = ""  # stripped source of this module's own body

    @property
    def node(self):
        return "::".join(self.path) or "crate"


def matching_brace(code, start):
    depth = 0
    for i in range(start, len(code)):
        if code[i] == "{":
            depth += 1
        elif code[i] == "}":
            depth -= 1
            if depth == 0:
                return i
    raise ValueError("unbalanced braces")


MOD_DECL = re.compile(
    r"((?:#\s*\[[^\]]*\]\s*)*)(?:pub(?:\s*\([^)]*\))?\s+)?mod\s+([A-Za-z_]\w*)\s*([;{])"
)


def load(module, src_dir, modules):
    """Fills in `module`'s children from its code, recursively."""
    code = module.code
    own, pos = [], 0
    for m in MOD_DECL.finditer(code):
        if m.start() < pos:
            continue
        attrs, name, kind = m.group(1), m.group(2), m.group(3)
        test = module.test or bool(re.search(r"cfg\s*\(\s*test\s*\)", attrs))
        child = Module(module.path + [name], module.file, module, test)
        if kind == "{":
            end = matching_brace(code, m.end() - 1)
            child.code = code[m.end() : end]
            own.append(code[pos : m.start()])
            pos = end + 1
        else:
            child.file = child_file(module, name, attrs, src_dir)
            child.code = strip(child.file.read_text())
        module.children[name] = child
        modules.append(child)
        load(child, src_dir, modules)
    own.append(code[pos:])
    module.code = "".join(own)


def child_file(module, name, attrs, src_dir):
    path_attr = re.search(r'path\s*=\s*"([^"]*)"', attrs)
    here = module.file.parent
    if path_attr:
        return here / path_attr.group(1)
    if module.file.name not in ("lib.rs", "mod.rs", "main.rs"):
        here = here / module.file.stem
    for candidate in (here / f"{name}.rs", here / name / "mod.rs"):
        if candidate.exists():
            return candidate
    sys.exit(f"import-cycles: no file for `mod {name}` in {module.file.relative_to(src_dir)}")


def expand_use(tree):
    """`a::{b, c::{d, e}}` -> [[a, b], [a, c, d], [a, c, e]] (self kept as a segment)."""
    tree = re.sub(r"\s+", "", tree)

    def parse(s, i):
        paths, prefix = [], []
        while i < len(s):
            if s[i] == "{":
                group, i = parse_group(s, i + 1)
                paths.extend(prefix + g for g in group)
                prefix = None
            elif s.startswith("::", i):
                i += 2
            elif s[i] in ",}":
                break
            else:
                m = SEGMENT.match(s, i)
                if not m:
                    i += 1
                    continue
                prefix.append(m.group(0))
                i = m.end()
        if prefix:
            paths.append(prefix)
        return paths, i

    def parse_group(s, i):
        group = []
        while i < len(s) and s[i] != "}":
            paths, i = parse(s, i)
            group.extend(paths)
            if i < len(s) and s[i] == ",":
                i += 1
        return group, i + 1

    return parse(tree, 0)[0]


USE = re.compile(r"\buse\s+([^;]*);")
PATH = re.compile(r"(?<![\w:])((?:crate|super)(?:\s*::\s*(?:[A-Za-z_]\w*|super))+)")


def paths_of(module):
    """Every `crate::`/`super::`/child-module path the module's own code names."""
    code = re.sub(r"\s*as\s+[A-Za-z_]\w*", "", module.code)
    found = []
    for m in USE.finditer(code):
        found.extend(expand_use(m.group(1)))
    rest = USE.sub("", code)
    for m in PATH.finditer(rest):
        found.append(re.split(r"\s*::\s*", m.group(1)))
    return found


def resolve(module, segments, root):
    """The module a path lands in (walking down the tree as far as it goes), or None for
    paths outside the crate (std, nalgebra, ...)."""
    if not segments:
        return None
    if segments[0] == "crate":
        at, rest = root, segments[1:]
    elif segments[0] == "super":
        at, rest = module, segments
        while rest and rest[0] == "super":
            at, rest = at.parent, rest[1:]
    elif segments[0] == "self":
        at, rest = module, segments[1:]
    elif segments[0] in module.children:
        at, rest = module, segments
    else:
        return None
    for seg in rest:
        if seg in at.children:
            at = at.children[seg]
        else:
            break
    return at


def graph(src_dir):
    root = Module([], src_dir / "lib.rs", None, False)
    root.code = strip(root.file.read_text())
    modules = [root]
    load(root, src_dir, modules)

    def node(m):
        # An inline non-test module is part of its file; a test module is a node of its own.
        while not m.test and m.parent is not None and m.file == m.parent.file:
            m = m.parent
        if m.test:
            return f"{m.file.relative_to(src_dir)} ({m.node})"
        return str(m.file.relative_to(src_dir))

    edges = {}
    for m in modules:
        edges.setdefault(node(m), set())
        for child in m.children.values():
            if not child.test and node(child) != node(m):
                edges[node(m)].add(node(child))
        for segments in paths_of(m):
            target = resolve(m, segments, root)
            if target is not None and node(target) != node(m):
                edges[node(m)].add(node(target))
    return edges


def cycles(edges):
    """Strongly connected components with more than one node (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def circle(edges, comp):
    """One circle through the component's first node (breadth-first, inside it)."""
    start, members = comp[0], set(comp)
    prev, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(edges[v]):
                if w == start:
                    path = [v]
                    while prev[path[-1]] is not None:
                        path.append(prev[path[-1]])
                    return list(reversed(path)) + [start]
                if w in members and w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    return comp


def layers(edges):
    """Files in dependency order: each file's imports come before it."""
    depth = {}

    def d(v):
        if v not in depth:
            depth[v] = 0
            depth[v] = 1 + max((d(w) for w in edges[v]), default=-1)
        return depth[v]

    for v in edges:
        d(v)
    return sorted(edges, key=lambda v: (depth[v], v)), depth


def main(argv):
    verbose = "-v" in argv
    args = [a for a in argv if a != "-v"]
    src_dir = Path(args[0]) if args else ROOT / "fmu-src" / "physics" / "src"
    edges = graph(src_dir.resolve())
    found = cycles(edges)
    if verbose and not found:
        order, depth = layers(edges)
        for v in order:
            print(f"{depth[v]:3} {v}")
    files = sum(1 for v in edges if "(" not in v)
    if found:
        for comp in found:
            print("import cycle among " + ", ".join(comp))
            print("    e.g. " + " -> ".join(circle(edges, comp)))
        print(f"import-cycles: {len(found)} cycle(s) among the {files} files of {src_dir}")
        return 1
    print(f"import-cycles: no cycle among the {files} files of {src_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
