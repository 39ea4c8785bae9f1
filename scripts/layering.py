#!/usr/bin/env python3
"""Checks the layering inside each workspace crate: no import cycle between its modules, and no
`use super::*` outside tests.

A file depends on another when it names an item of that file's module: `crate::a::b::X`,
`super::x::Y`, `self::x`, or a child module in a `use` (`use child::X`). Test modules
(`#[cfg(test)] mod tests`) and `tests.rs` or `*_tests.rs` files are left out: they may look at every layer.

Modules are compared as units: under every module, each child module together with its own
submodules is one unit, and the units under one parent must depend on each other one way (a
cycle among siblings is printed). A parent's own file is the container of its children, not a
sibling of them: `objects/mod.rs` may re-export `objects::kinds` while `kinds` uses the
`Creator` that `objects/mod.rs` defines. With `--files`, every file is its own unit instead
(the strict view, parent files included).

A glob import of the parent (`use super::*`) hides which items a module takes from where; only
test modules may use it.

Usage: scripts/layering.py [--files] [CRATE_DIR ...]   (default: every crate with a
src/lib.rs or src/main.rs). Exits 1 if a crate has a cycle or a glob import of its parent outside tests.
"""
import os
import re
import sys


def modules(src):
    """Module path (tuple) -> file, for one crate's src directory."""
    out = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith('.rs'):
                continue
            rel = os.path.relpath(os.path.join(root, f), src)[:-3].split(os.sep)
            if rel[-1] in ('lib', 'main', 'mod'):
                rel = rel[:-1]
            if rel and (rel[-1] == 'tests' or rel[-1].endswith('_tests')):
                continue
            out[tuple(rel)] = os.path.join(root, f)
    return out


def strip_tests(text):
    """The text without its test modules (each `#[cfg(test)] mod x { ... }` block)."""
    pattern = re.compile(
        r'#\[cfg\((all\()?test\b[^\]]*\]\s*(#\[[^\]]*\]\s*)*(pub(\(\w+\))? )?mod \w+ \{')
    while True:
        m = pattern.search(text)
        if not m:
            return text
        depth, i = 1, m.end()
        while i < len(text) and depth:
            depth += {'{': 1, '}': -1}.get(text[i], 0)
            i += 1
        text = text[:m.start()] + text[i:]


def expand(tree):
    """`a::{b, c::{d, e}}` -> ['a::b', 'a::c::d', 'a::c::e']."""
    tree = re.sub(r'\s+', '', tree)
    i = tree.find('{')
    if i < 0:
        return [tree]
    prefix = tree[:i]
    depth, parts, cur = 0, [], ''
    body = tree[i + 1:tree.rfind('}')]
    for ch in body:
        if ch == ',' and depth == 0:
            parts.append(cur)
            cur = ''
            continue
        depth += ch == '{'
        depth -= ch == '}'
        cur += ch
    parts.append(cur)
    return [x for p in parts if p for x in expand(prefix + p)]


def paths(text):
    text = re.sub(r'//[^\n]*', '', text)
    for m in re.finditer(r'\buse\s+([^;]+);', text):
        for p in expand(m.group(1)):
            yield p.split(' as ')[0], True
    for m in re.finditer(r'\b((?:crate|super|self)(?:::\w+)+)', text):
        yield m.group(1), False


def resolve(path, here, mods, is_use):
    segs = path.split('::')
    if segs[0] == 'crate':
        base, segs = (), segs[1:]
    elif segs[0] in ('super', 'self'):
        base = here
        while segs and segs[0] in ('super', 'self'):
            if segs[0] == 'super':
                base = base[:-1]
            segs = segs[1:]
    elif is_use and here + (segs[0],) in mods:
        base = here
    else:
        return None
    target = None
    for k in range(len(segs), -1, -1):
        cand = base + tuple(segs[:k])
        if cand in mods:
            target = cand
            break
    return target


def sccs(graph):
    index, low, stack, on, out, n = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = n[0]
        n[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(comp)

    sys.setrecursionlimit(10000)
    for v in list(graph):
        if v not in index:
            visit(v)
    return out


def file_graph(mods):
    graph = {}
    for here, f in mods.items():
        deps = set()
        for p, is_use in paths(strip_tests(open(f).read())):
            t = resolve(p, here, mods, is_use)
            if t is not None and t != here:
                deps.add(t)
        graph[here] = deps
    return graph


def sibling_cycles(mods, graph):
    """Cycles among the child units of every module."""
    out = []
    for parent in sorted(mods):
        children = sorted({m[:len(parent) + 1] for m in mods
                           if len(m) > len(parent) and m[:len(parent)] == parent})
        if len(children) < 2:
            continue
        unit_graph = {c: set() for c in children}
        for v, ws in graph.items():
            cv = v[:len(parent) + 1]
            if cv not in unit_graph or v[:len(parent)] != parent:
                continue
            for w in ws:
                cw = w[:len(parent) + 1]
                if cw in unit_graph and cw != cv and w[:len(parent)] == parent:
                    unit_graph[cv].add(cw)
        out += [sorted(c) for c in sccs(unit_graph) if len(c) > 1]
    return out


def crate_cycles(crate, files=False):
    mods = modules(os.path.join(crate, 'src'))
    graph = file_graph(mods)
    if files:
        return [sorted(c) for c in sccs(graph) if len(c) > 1], len(mods)
    return sibling_cycles(mods, graph), len(mods)


def parent_globs(crate):
    """Files that glob-import their parent outside test modules."""
    out = []
    for f in modules(os.path.join(crate, 'src')).values():
        if re.search(r'\buse\s+super::\*\s*;', strip_tests(open(f).read())):
            out.append(os.path.relpath(f, crate))
    return out


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    args = sys.argv[1:]
    files = '--files' in args
    args = [a for a in args if a != '--files']
    crates = args or sorted(
        os.path.join(root, d) for d in os.listdir(root)
        if os.path.exists(os.path.join(root, d, 'src', 'lib.rs'))
        or os.path.exists(os.path.join(root, d, 'src', 'main.rs')))
    bad = 0
    for c in crates:
        cycles, n = crate_cycles(c, files)
        name = os.path.basename(c.rstrip('/'))
        print(f'{name}: {n} modules, {len(cycles)} cycles')
        for comp in cycles:
            bad += 1
            print('  cycle: ' + ' <-> '.join('::'.join(m) or 'lib' for m in comp))
        for f in parent_globs(c):
            bad += 1
            print(f'  `use super::*` outside tests: {f}')
    sys.exit(1 if bad else 0)


if __name__ == '__main__':
    main()
