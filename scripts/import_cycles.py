#!/usr/bin/env python3
"""Import circles between the modules of a crate (`scripts/import_cycles.py crates/cordis-es/src`).

A module is a file (`a/mod.rs` is `a`). An edge A -> B is a path in A's code (comments and
`#[cfg(test)]` modules left out) that names an item of B: `crate::b::X`, `super::X`, `self::x::X`
and `use` trees. A path through a facade (`crate::cost::Objective`, where `cost/mod.rs` says
`pub use objective::Objective`) counts as an edge to the file that defines the item, so a parent
that only declares and re-exports its children is no circle with them. Prints the circles
(strongly connected components) and exits 1 when there is one; `-v` prints every edge;
`--allow PREFIX` tolerates (still prints) a circle whose modules all lie under PREFIX.
"""
import os
import re
import sys

root = sys.argv[1]
verbose = '-v' in sys.argv
allowed = [sys.argv[i + 1] for i, a in enumerate(sys.argv) if a == '--allow']
files = {}
for dirpath, _, names in os.walk(root):
    for name in names:
        if name.endswith('.rs'):
            path = os.path.join(dirpath, name)
            parts = os.path.relpath(path, root)[:-3].split(os.sep)
            if parts[-1] in ('mod', 'lib', 'main'):
                parts = parts[:-1]
            files[tuple(parts)] = path


def code_of(path):
    src = open(path).read()
    src = re.sub(r'//[^\n]*', '', src)
    src = re.sub(r'/\*.*?\*/', '', src, flags=re.S)
    src = re.sub(r'"(\\.|[^"\\])*"', '""', src)
    cut = re.search(r'#\[cfg\(test\)\]\s*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{', src)
    return src[:cut.start()] if cut else src


codes = {m: code_of(p) for m, p in files.items()}


def expand_tree(tree):
    """`a::{b, c::{d, e}}` -> [a::b, a::c::d, a::c::e]."""
    tree = re.sub(r'\s+as\s+', '@', tree)
    tree = re.sub(r'\s+', '', tree)
    if '{' not in tree or '}' not in tree:
        return [tree]
    i = tree.index('{')
    head, inner = tree[:i], tree[i + 1:tree.rindex('}')]
    items, depth, cur = [], 0, ''
    for ch in inner:
        if ch == ',' and depth == 0:
            items.append(cur)
            cur = ''
            continue
        depth += (ch == '{') - (ch == '}')
        cur += ch
    if cur:
        items.append(cur)
    out = []
    for item in items:
        out += [head + x for x in expand_tree(item)]
    return out


def absolute(module, path):
    """A path as a tuple from the crate root, or None for an external crate."""
    parts = [p for p in path.split('::') if p]
    if not parts:
        return None
    base = list(module) if files[module].endswith(('mod.rs', 'lib.rs', 'main.rs')) else list(module[:-1])
    if parts[0] == 'crate':
        return tuple(parts[1:])
    if parts[0] == 'self':
        return tuple(list(module) + parts[1:])
    if parts[0] == 'super':
        cur = list(module)
        while parts and parts[0] == 'super':
            cur = cur[:-1]
            parts = parts[1:]
        return tuple(cur + parts)
    if tuple(list(module) + parts[:1]) in files:  # a child module named relatively
        return tuple(list(module) + parts)
    return None


# Re-exports: (module, name) -> the path it stands for.
reexports = {}
for m, src in codes.items():
    for u in re.finditer(r'pub(\([^)]*\))?\s+use\s+([^;]+);', src):
        for p in expand_tree(u.group(2)):
            p, _, alias = p.partition('@')
            p = p.rstrip(':')
            target = absolute(m, p)
            if target is None:
                continue
            name = alias or target[-1]
            if name in ('*', 'self'):
                continue
            reexports[(m, name)] = target


def resolve(path, depth=0):
    """The file that defines the item `path` names."""
    path = tuple(x for x in path if x not in ('*', 'self'))
    for k in range(len(path), -1, -1):
        head = path[:k]
        if head in files:
            if k < len(path) and (head, path[k]) in reexports and depth < 20:
                return resolve(reexports[(head, path[k])] + path[k + 1:], depth + 1)
            return head
    return None


edges = {m: set() for m in files}
for m, src in codes.items():
    paths = []
    for u in re.finditer(r'\buse\s+([^;]+);', src):
        paths += [p.split('@')[0] for p in expand_tree(u.group(1))]
    paths += re.findall(r'(?<![\w:])((?:crate|super|self)(?:::\w+)+)', src)
    for p in paths:
        target = absolute(m, p.rstrip(':'))
        if target is None:
            continue
        t = resolve(target)
        if t is not None and t != m:
            edges[m].add(t)

index, low, stack, on_stack, comps = {}, {}, [], set(), []
sys.setrecursionlimit(10000)


def connect(v):
    index[v] = low[v] = len(index)
    stack.append(v)
    on_stack.add(v)
    for w in sorted(edges[v]):
        if w not in index:
            connect(w)
            low[v] = min(low[v], low[w])
        elif w in on_stack:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        comp = []
        while True:
            w = stack.pop()
            on_stack.discard(w)
            comp.append(w)
            if w == v:
                break
        comps.append(comp)


for v in sorted(files):
    if v not in index:
        connect(v)


def name(m):
    return '::'.join(m) or '(crate root)'


if verbose:
    for m in sorted(files):
        print(name(m), '->', ', '.join(sorted(name(t) for t in edges[m])))
cycles = [sorted(c) for c in comps if len(c) > 1]
print(f'{root}: {len(files)} modules, {sum(map(len, edges.values()))} imports, {len(cycles)} circles')
for c in cycles:
    inner = {a: sorted(b for b in edges[a] if b in c) for a in c}
    print('circle:', '; '.join(f'{name(a)} -> {", ".join(map(name, inner[a]))}' for a in c))


def tolerated(c):
    return any(all(name(m) == a or name(m).startswith(a + '::') for m in c) for a in allowed)


for c in cycles:
    if tolerated(c):
        print('(tolerated by --allow)', ' <-> '.join(map(name, c)))
sys.exit(1 if any(not tolerated(c) for c in cycles) else 0)
