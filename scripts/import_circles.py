#!/usr/bin/env python3
"""Import circles between the files of each crate (issue #36: names and rooms that explain themselves).

Every top-level module of a crate (a file under src/, or a folder counted as one) is a node; a
`crate::x` path anywhere in its code (comments left out) is an edge to module x, with names the
crate root re-exports (`pub use x::Name`) followed to x. A circle is a strongly connected set of
two or more modules. Usage: scripts/import_circles.py [-v] crates/gs-core crates/gs-train ...
(no crate: every crate under crates/). -v lists each circle's edges.
"""
import re, sys, os
from pathlib import Path

def strip_comments(t):
    t = re.sub(r'//[^\n]*', '', t)
    return re.sub(r'/\*.*?\*/', '', t, flags=re.S)

def top_modules(src):
    mods = {}
    for p in src.iterdir():
        if p.name in ('lib.rs', 'main.rs'): continue
        if p.suffix == '.rs': mods[p.stem] = [p]
        elif p.is_dir(): mods[p.name] = sorted(p.rglob('*.rs'))
    return mods

def reexports(lib, mods):
    m = {}
    t = strip_comments(lib.read_text())
    for mm in re.finditer(r'pub use\s+(\w+)::(\{[^;]*\}|\w+)\s*;', t, re.S):
        if mm.group(1) not in mods: continue
        for name in re.findall(r'\w+', mm.group(2)):
            m[name] = mm.group(1)
    return m

def targets(text, mods, rex):
    out = set()
    # expand `crate::{a, b::c}` groups and plain `crate::x` paths
    for mm in re.finditer(r'crate::(\{|\w+)', text):
        if mm.group(1) == '{':
            depth, i = 1, mm.end()
            while depth:
                depth += {'{': 1, '}': -1}.get(text[i], 0); i += 1
            inner = text[mm.end():i-1]
            # top-level names in the group
            d, cur, names = 0, '', []
            for ch in inner:
                if ch == '{': d += 1
                elif ch == '}': d -= 1
                if ch == ',' and d == 0: names.append(cur); cur = ''
                else: cur += ch
            names.append(cur)
            for n in names:
                w = re.match(r'\s*(\w+)', n)
                if w: out.add(w.group(1))
        else:
            out.add(mm.group(1))
    res = set()
    for n in out:
        if n in mods: res.add(n)
        elif n in rex: res.add(rex[n])
    return res

def scc(nodes, edges):
    index, low, st, on, comps, c = {}, {}, [], set(), [], [0]
    sys.setrecursionlimit(10000)
    def visit(v):
        index[v] = low[v] = c[0]; c[0] += 1; st.append(v); on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index: visit(w); low[v] = min(low[v], low[w])
            elif w in on: low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = st.pop(); on.discard(w); comp.append(w)
                if w == v: break
            comps.append(sorted(comp))
    for v in sorted(nodes):
        if v not in index: visit(v)
    return [c for c in comps if len(c) > 1]

verbose = '-v' in sys.argv
total = 0
crates = [a for a in sys.argv[1:] if a != '-v'] or sorted(str(p) for p in Path('crates').iterdir() if (p / 'src').is_dir())
for crate in crates:
    src = Path(crate) / 'src'
    mods = top_modules(src)
    lib = src / 'lib.rs'
    rex = reexports(lib, mods) if lib.exists() else {}
    edges = {}
    for m, files in mods.items():
        t = ''.join(strip_comments(f.read_text()) for f in files)
        edges[m] = targets(t, mods, rex) - {m}
    comps = scc(mods, edges)
    total += len(comps)
    print(f'{Path(crate).name}: {sum(len(e) for e in edges.values())} edges, {len(comps)} circle(s)')
    for comp in comps:
        inner = sum(1 for a in comp for b in edges[a] if b in comp)
        print(f'  circle of {len(comp)} files ({inner} edges): {" ".join(comp)}')
        if verbose:
            for a in comp:
                print(f'    {a} -> {" ".join(sorted(b for b in edges[a] if b in comp))}')
print(f'total circles: {total}')
