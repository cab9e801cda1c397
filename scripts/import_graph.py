#!/usr/bin/env python3
"""The import graph of src/: which file names which (by `use` or a path in
the code), its circles, and what the core names of the front ends.

    python3 scripts/import_graph.py            # exit 1 on a circle or a core → front-end edge
    python3 scripts/import_graph.py --dot      # the graph, for graphviz
    python3 scripts/import_graph.py --src DIR  # another tree (e.g. an older commit's src/)

A file's references are the paths it writes: `crate::a::b`, `super::x`,
`self::y` and bare child-module paths in `use` lines; each resolves to the
file of the deepest module it names (an item resolves to its module's file).
A `mod` declaration is not a reference, and neither is a path between a
module and one of its ancestors (a parent's re-exports and shared items are
its children's as much as its own, as Rust's privacy has it): a circle is
one between modules neither of which contains the other, such as two
siblings calling each other.

The same at folder level: a file is in its folder (src/sweep/parse/x.rs in
sweep/parse, a mod.rs in its own), and two folders neither of which
contains the other must not name each other, directly or around a circle.

The front ends (`cli`, `explore`, `plot`, `progress`, `slurm`, `main`) may
name the core; the core must not name them (the compiler also enforces it:
`cargo build --lib --no-default-features`).
"""
import re
import sys
from pathlib import Path

SRC = Path(sys.argv[sys.argv.index("--src") + 1]).resolve() if "--src" in sys.argv else Path(__file__).resolve().parent.parent / "src"
FRONT = {"cli", "explore", "plot", "progress", "slurm", "main"}


def module_of(p: Path):
    rel = p.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod":
        parts = parts[:-1]
    if parts == ["lib"]:
        return ()
    return tuple(parts)


def components(edges):
    """The strongly connected components of more than one node (Tarjan)."""
    index, low, stack, on, sccs, counter = {}, {}, [], set(), [], [0]

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                strong(w)
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
            if len(comp) > 1:
                sccs.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            strong(v)
    return sccs


def main():
    files = {}
    for p in sorted(SRC.rglob("*.rs")):
        files[module_of(p)] = p
    mods = set(files)

    def resolve(path):
        """The deepest module of `path` (a tuple) that has a file."""
        for n in range(len(path), -1, -1):
            if tuple(path[:n]) in mods:
                return tuple(path[:n])
        return None

    edges = {}
    for mod, p in files.items():
        text = p.read_text()
        # Drop comments and strings' contents roughly: line comments only.
        code = "\n".join(l.split("//")[0] for l in text.splitlines())
        # Test modules are not part of the graph of the library.
        code = re.split(r"#\[cfg\(test\)\]\s*mod tests", code)[0]
        is_mod_rs = p.name in ("mod.rs", "lib.rs", "main.rs")
        refs = set()

        def add(path):
            r = resolve(path)
            # A module and its ancestors are one unit (a parent's shared
            # items, a child's re-exports): only edges between modules
            # neither of which contains the other count.
            if r is None or r[: len(mod)] == mod or mod[: len(r)] == r:
                return
            refs.add(r)

        def expand(prefix, tree):
            # `a::{b, c::{d}}` → a::b, a::c::d
            tree = tree.strip()
            m = re.match(r"^([\w:]*?)(?:::)?\{(.*)\}$", tree, re.S)
            if m:
                head = [x for x in m.group(1).split("::") if x]
                depth, item, items = 0, "", []
                for ch in m.group(2):
                    if ch == "," and depth == 0:
                        items.append(item)
                        item = ""
                        continue
                    depth += ch == "{"
                    depth -= ch == "}"
                    item += ch
                items.append(item)
                for it in items:
                    if it.strip():
                        expand(prefix + head, it)
            else:
                name = tree.split(" as ")[0].strip()
                add(prefix + [x for x in name.split("::") if x and x != "self"])

        def base(first):
            return {"crate": [], "super": list(mod[:-1]), "self": list(mod)}.get(first)

        for m in re.finditer(r"\buse\s+([^;]+);", code):
            tree = m.group(1).strip()
            first = tree.split("::")[0]
            b = base(first)
            if b is not None:
                expand(b, tree[len(first):].lstrip(":"))
            elif is_mod_rs and first in {x[len(mod)] for x in mods if len(x) == len(mod) + 1 and x[: len(mod)] == mod}:
                expand(list(mod), tree)
        for m in re.finditer(r"\b(crate|super|self)((?:::\w+)+)", code):
            b = base(m.group(1))
            if b is not None:
                add(b + m.group(2).strip(":").split("::"))
        edges[mod] = refs

    name = lambda m: str(files[m].relative_to(SRC.parent))
    if "--dot" in sys.argv:
        print("digraph src {")
        for a, bs in sorted(edges.items()):
            for b in sorted(bs):
                print(f'  "{name(a)}" -> "{name(b)}";')
        print("}")
        return 0

    sccs = components(edges)
    # The same at folder level: a file's folder (src/sweep/parse/x.rs is in
    # sweep/parse; lib.rs and main.rs in the root), an edge between two
    # folders neither of which contains the other.
    folder = {m: (m if files[m].name == "mod.rs" else m[:-1]) for m in files}
    fedges = {}
    for a, bs in edges.items():
        fa = folder[a]
        for b in bs:
            fb = folder[b]
            if fa[: len(fb)] == fb or fb[: len(fa)] == fa:
                continue
            fedges.setdefault(fa, set()).add(fb)
            fedges.setdefault(fb, set())
    fsccs = components(fedges)
    fname = lambda f: "src/" + "/".join(f) if f else "src"
    bad = 0
    for comp in fsccs:
        bad += 1
        print("folder circle:", ", ".join(fname(f) for f in comp))
        for a in comp:
            for b in sorted(edges):
                if folder[b] == a:
                    for c in sorted(edges[b]):
                        if folder[c] in comp and folder[c] != a and not (a[: len(folder[c])] == folder[c] or folder[c][: len(a)] == a):
                            print(f"    {name(b)} -> {name(c)}")

    for comp in sccs:
        bad += 1
        print("circle:", ", ".join(name(m) for m in comp))
        for a in comp:
            for b in sorted(edges[a]):
                if b in comp:
                    print(f"    {name(a)} -> {name(b)}")
    for a, bs in sorted(edges.items()):
        if a and a[0] in FRONT:
            continue
        for b in bs:
            if b and b[0] in FRONT:
                bad += 1
                print(f"core names a front end: {name(a)} -> {name(b)}")
    n_edges = sum(len(b) for b in edges.values())
    print(f"{len(files)} files, {n_edges} edges, {len(sccs)} circles; {len(set(folder.values()))} folders, {len(fsccs)} folder circles")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
