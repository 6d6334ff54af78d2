#!/usr/bin/env python3
"""Import circles between the source files of one Rust crate.

Usage: import_cycles.py SRC_DIR [SRC_DIR ...]   (each a crate's `src`, e.g. firmware/core/src)
       import_cycles.py --self-test               (the checker on two small made-up crates)

Each file under SRC_DIR is a module (`a.rs` and `a/mod.rs` are `crate::a`, `a/b.rs` is `crate::a::b`). An
edge A -> B is a path in A's code (a `use` line or an inline path, test modules left out) that names B:
`crate::b::...`, `super::...` or `self::...` resolved against A's place. A path to an item of the crate
root (`crate::Item`) is followed through the root's `pub use` re-exports to the module that defines the
item; the root itself (lib.rs/main.rs: module declarations and re-exports) takes part in no cycle.
Prints every cycle (one strongly connected component of more than one file per line, and one shortest
cycle through it) and exits 1 if there is any, else 0.
"""
import os
import re
import sys


def strip_comments_and_tests(text):
    """The code without comments, string literals and `#[cfg(test)]` items (test modules)."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    out, i = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]", text):
        if m.start() < i:
            continue
        out.append(text[i:m.start()])
        j = m.end()
        # skip the attributed item: up to the end of its `{...}` block or its `;`
        depth, k = 0, j
        while k < len(text):
            c = text[k]
            if c == "{":
                depth += 1
            elif c == "}":
                depth -= 1
                if depth == 0:
                    k += 1
                    break
            elif c == ";" and depth == 0:
                k += 1
                break
            k += 1
        i = k
    out.append(text[i:])
    return "".join(out)


def expand_use(tree):
    """`a::{b, c::{d, e}}` -> ['a::b', 'a::c::d', 'a::c::e'] (whitespace removed)."""
    tree = re.sub(r"\s+", "", re.sub(r"\s+as\s+", "@as@", tree))
    depth, start = 0, None
    for i, c in enumerate(tree):
        if c == "{":
            if depth == 0:
                start = i
            depth += 1
        elif c == "}":
            depth -= 1
            if depth == 0:
                prefix, inner, rest = tree[:start], tree[start + 1:i], tree[i + 1:]
                parts, d, s = [], 0, 0
                for j, ch in enumerate(inner):
                    if ch == "{":
                        d += 1
                    elif ch == "}":
                        d -= 1
                    elif ch == "," and d == 0:
                        parts.append(inner[s:j])
                        s = j + 1
                parts.append(inner[s:])
                return [p for part in parts if part for p in expand_use(prefix + part + rest)]
    return [tree]


def module_paths(src):
    """{module path tuple: file} for every .rs file under src; the root is ()."""
    mods = {}
    for dirpath, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            rel = os.path.relpath(os.path.join(dirpath, f), src)
            parts = rel[:-3].split(os.sep)
            if parts[-1] == "mod":
                parts = parts[:-1]
            if parts in (["lib"], ["main"]):
                parts = []
            mods[tuple(parts)] = os.path.join(dirpath, f)
    return mods


def paths_in(code, children=()):
    """Every crate-relative path the code names: use trees expanded, plus inline `crate::`/`super::`
    paths, plus paths that start with the name of one of the module's own child modules
    (`children`: Rust 2018 resolves `child::x` relative to the module), written as `self::child::x`."""
    found = []
    for m in re.finditer(r"\buse\s+([^;]*);", code):
        for p in expand_use(m.group(1)):
            head = p.split("::", 1)[0]
            if head in ("crate", "super", "self"):
                found.append(p)
            elif head in children:
                found.append("self::" + p)
    body = re.sub(r"\buse\s+[^;]*;", "", code)
    for m in re.finditer(r"\b((?:crate|super)(?:::[A-Za-z_][A-Za-z0-9_]*)+)", body):
        found.append(m.group(1))
    for c in children:
        for m in re.finditer(r"(?<![:\w])(" + re.escape(c) + r"(?:::[A-Za-z_][A-Za-z0-9_]*)+)", body):
            found.append("self::" + m.group(1))
    return found


def resolve(path, here, mods):
    """The module tuple a path names, or None; `here` is the module tuple of the file the path is in."""
    segs = [s for s in path.partition("@as@")[0].split("::") if s]
    if not segs:
        return None
    if segs[0] == "crate":
        base, segs = (), segs[1:]
    else:
        base = here
        while segs and segs[0] in ("super", "self"):
            if segs[0] == "super":
                base = base[:-1]
            segs = segs[1:]
    # the longest prefix that is a module file
    best = base if base in mods else None
    cur = base
    for s in segs:
        cur = cur + (s,)
        if cur in mods:
            best = cur
        else:
            break
    if best is None:
        return None
    if best == () and segs:
        return ("<root item>", segs[0])
    return best


def root_reexports(root_code, mods):
    """{item name: module tuple} from the crate root's `pub use` lines."""
    table = {}
    for m in re.finditer(r"\bpub\s+use\s+([^;]*);", root_code):
        for p in expand_use(m.group(1)):
            p, _, alias = p.partition("@as@")
            segs = [s for s in p.split("::") if s and s != "crate" and s != "self"]
            if not segs:
                continue
            name = alias or segs[-1]
            mod, cur = None, ()
            for s in segs[:-1]:
                cur = cur + (s,)
                if cur in mods:
                    mod = cur
            if mod is not None:
                table[name] = mod
    return table


def graph(src):
    mods = module_paths(src)
    codes = {m: strip_comments_and_tests(open(f, encoding="utf-8").read()) for m, f in mods.items()}
    reexp = root_reexports(codes.get((), ""), mods)
    edges = {m: set() for m in mods}
    for m, code in codes.items():
        if m == ():
            continue
        children = {c[-1] for c in mods if len(c) == len(m) + 1 and c[: len(m)] == m}
        for p in paths_in(code, children):
            t = resolve(p, m, mods)
            if isinstance(t, tuple) and t and t[0] == "<root item>":
                t = reexp.get(t[1], ())
            if t is None or t == () or t == m:
                continue
            edges[m].add(t)
    return mods, edges


def sccs(nodes, edges):
    index, low, stack, on, out, n = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = n[0]
        n[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
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
    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def shortest_cycle(comp, edges):
    comp = set(comp)
    best = None
    for s in sorted(comp):
        prev, frontier, seen = {s: None}, [s], {s}
        found = None
        while frontier and found is None:
            nxt = []
            for v in frontier:
                for w in sorted(edges[v]):
                    if w == s:
                        found = v
                        break
                    if w in comp and w not in seen:
                        seen.add(w)
                        prev[w] = v
                        nxt.append(w)
                if found is not None:
                    break
            frontier = nxt
        if found is not None:
            path, v = [], found
            while v is not None:
                path.append(v)
                v = prev[v]
            path.reverse()
            if best is None or len(path) < len(best):
                best = path
    return best


def name(m):
    return "::".join(m) or "crate"


def self_test():
    """The checker on two small crates: one with a circle through a facade's re-export, an inline path
    and a child module's relative path, one without; 0 if both answer as they should."""
    import tempfile

    crates = {
        "circle": {
            "lib.rs": "mod a;\nmod b;\npub use b::B;\n",
            "a.rs": "use crate::B;\npub struct A;\n",
            "b/mod.rs": "mod c;\npub struct B;\nfn f() { c::g() }\n",
            "b/c.rs": "pub fn g() { let _ = crate::a::A; }\n",
        },
        "layers": {
            "lib.rs": "mod a;\nmod b;\n",
            "a.rs": "// use crate::b;\npub struct A;\n#[cfg(test)]\nmod tests { use crate::b::B; }\n",
            "b.rs": "use crate::{a::A};\npub struct B(A);\nconst S: &str = \"crate::b\";\n",
        },
    }
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for crate, files in crates.items():
            for rel, text in files.items():
                path = os.path.join(tmp, crate, rel)
                os.makedirs(os.path.dirname(path), exist_ok=True)
                with open(path, "w", encoding="utf-8") as f:
                    f.write(text)
            mods, edges = graph(os.path.join(tmp, crate))
            comps = [sorted(c) for c in sccs(mods, edges) if len(c) > 1]
            want = [[("a",), ("b",), ("b", "c")]] if crate == "circle" else []
            if comps != want:
                print(f"self-test {crate}: found {comps}, expected {want}", file=sys.stderr)
                ok = False
    print("self-test " + ("passed" if ok else "FAILED"))
    return 0 if ok else 1


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    bad = 0
    for src in argv[1:]:
        if not os.path.isdir(src):
            print(f"{src}: not a directory", file=sys.stderr)
            return 2
        mods, edges = graph(src)
        comps = [c for c in sccs(mods, edges) if len(c) > 1]
        n_edges = sum(len(e) for e in edges.values())
        if not comps:
            print(f"{src}: no import cycle ({len(mods)} files, {n_edges} imports)")
            continue
        bad += 1
        print(f"{src}: {len(comps)} import cycle(s) ({len(mods)} files, {n_edges} imports)")
        for c in sorted(comps, key=len, reverse=True):
            cyc = shortest_cycle(c, edges)
            print(f"  {len(c)} files: {', '.join(sorted(name(m) for m in c))}")
            print(f"    e.g. {' -> '.join(name(m) for m in cyc + [cyc[0]])}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
