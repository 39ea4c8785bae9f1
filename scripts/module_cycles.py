#!/usr/bin/env python3
"""Finds import cycles between the modules (files) of each workspace crate.

A file depends on another when it names an item of that file's module: `crate::a::b::X`,
`super::x::Y`, `self::x`, or a child module in a `use` (`use child::X`). A parent's `mod child;`
declaration is not a dependency, and test modules (`#[cfg(test)] mod tests`) and `tests.rs`
files are left out: they may look at every layer. Prints every strongly connected component of
more than one file, per crate; exits 1 if there is one.

Usage: scripts/module_cycles.py [CRATE_DIR ...]   (default: every crate with a src/lib.rs)
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
            if rel and rel[-1] == 'tests':
                continue
            out[tuple(rel)] = os.path.join(root, f)
    return out


def strip_tests(text):
    m = re.search(r'#\[cfg\(test\)\]\s*(pub(\(\w+\))? )?mod \w+ \{', text)
    return text[:m.start()] if m else text


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


def crate_cycles(crate):
    mods = modules(os.path.join(crate, 'src'))
    graph = {}
    for here, f in mods.items():
        deps = set()
        for p, is_use in paths(strip_tests(open(f).read())):
            t = resolve(p, here, mods, is_use)
            if t is not None and t != here:
                deps.add(t)
        graph[here] = deps
    return [sorted(c) for c in sccs(graph) if len(c) > 1], len(mods)


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    crates = sys.argv[1:] or sorted(
        os.path.join(root, d) for d in os.listdir(root)
        if os.path.exists(os.path.join(root, d, 'src', 'lib.rs')))
    bad = 0
    for c in crates:
        cycles, n = crate_cycles(c)
        name = os.path.basename(c.rstrip('/'))
        print(f'{name}: {n} modules, {len(cycles)} cycles')
        for comp in cycles:
            bad += 1
            print('  cycle: ' + ' <-> '.join('::'.join(m) or 'lib' for m in comp))
    sys.exit(1 if bad else 0)


if __name__ == '__main__':
    main()
