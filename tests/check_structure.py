#!/usr/bin/env python3
"""check_structure.py: the house rules of the code, read from the built objects and the sources.

    python3 tests/check_structure.py BUILD_DIR      # exit 0 when every rule holds, 1 otherwise
    python3 tests/check_structure.py --self-test    # the checker's own test on made-up symbol tables

Rules (docs/render-core.md, "The map"):
  1. No file-level dependency cycle among the libraries' objects. An arrow A -> B means object A
     uses a global symbol that object B defines (`nm`: undefined in A, defined in B). A cycle is a
     strongly connected component of two or more objects (Tarjan's algorithm).
  2. Modules depend one way: renderer -> sh -> photonmap, renderer -> walk, sh -> walk. No object
     of a lower module uses a symbol of a higher one (walk and photonmap are leaves).
  3. Inside renderer/, folders are layers and depend downward only, in the order of
     RENDERER_LAYERS (core/ at the bottom, cli/ at the top): an object may use symbols of its own
     folder and of the folders below it.
  4. No two sources of one library share a file name (ar keeps members by name alone: an
     incremental `ar r` would replace one with the other).
  5. No library source file over 1000 lines; no internal header over 300 (the public header of
     each module, walk.h, photonmap.h, sh.h and renderer.h, is the module's whole contract and
     is not capped).
Each broken rule prints one line naming the files and the symbols that tie them.
"""
import os
import subprocess
import sys

MODULES = ["walk", "photonmap", "sh", "renderer"]
# Which modules each module may use (rule 2).
ALLOWED = {
    "walk": set(),
    "photonmap": set(),
    "sh": {"photonmap", "walk"},
    "renderer": {"sh", "photonmap", "walk"},
}
# renderer/'s folders from the bottom up (docs/render-core.md, "The map").
RENDERER_LAYERS = ["core", "media", "scene", "transport", "integrators", "bake", "render", "load",
                   "compare", "dist", "cli"]
PUBLIC_HEADERS = {"walk/walk.h", "photonmap/photonmap.h", "sh/sh.h", "renderer/renderer.h"}
MAX_SOURCE_LINES = 1000
MAX_INTERNAL_HEADER_LINES = 300


def read_symbols(obj):
    """(defined, undefined) global symbol sets of one object file, from nm."""
    out = subprocess.run(["nm", "-P", obj], check=True, capture_output=True, text=True).stdout
    defined, undefined = set(), set()
    for line in out.splitlines():
        parts = line.split()
        if len(parts) < 2:
            continue
        name, kind = parts[0], parts[1]
        if kind == "U":
            undefined.add(name)
        elif kind in "TDBRCVWGS" and kind.isupper():
            defined.add(name)
    return defined, undefined


def edges(tables):
    """tables: {unit: (defined, undefined)} -> {unit: {other: sorted symbols}} (A uses B's)."""
    owner = {}
    for unit, (defined, _) in tables.items():
        for sym in defined:
            owner.setdefault(sym, unit)
    out = {u: {} for u in tables}
    for unit, (_, undefined) in tables.items():
        for sym in undefined:
            b = owner.get(sym)
            if b is not None and b != unit:
                out[unit].setdefault(b, []).append(sym)
    return out


def strongly_connected(graph):
    """Tarjan's algorithm (iterative); returns the components of two or more nodes."""
    index, low, on_stack, stack, comps = {}, {}, set(), [], []
    counter = [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]; counter[0] += 1
        stack.append(root); on_stack.add(root)
        while work:
            node, it = work[-1]
            advanced = False
            for nxt in it:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter[0]; counter[0] += 1
                    stack.append(nxt); on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    advanced = True
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop(); on_stack.discard(w); comp.append(w)
                    if w == node:
                        break
                if len(comp) > 1:
                    comps.append(sorted(comp))
    return comps


def module_of(unit):
    return unit.split("/", 1)[0]


def check_graph(tables):
    """Rules 1 and 2 on symbol tables; returns the list of problems (one line each)."""
    problems = []
    graph = edges(tables)
    for comp in strongly_connected(graph):
        ties = []
        members = set(comp)
        for a in comp:
            for b, syms in sorted(graph[a].items()):
                if b in members:
                    ties.append("%s -> %s (%s)" % (a, b, ", ".join(sorted(syms)[:4])))
        problems.append("dependency cycle among %d files: %s" % (len(comp), "; ".join(ties)))
    for a, targets in sorted(graph.items()):
        for b, syms in sorted(targets.items()):
            ma, mb = module_of(a), module_of(b)
            if ma != mb and mb not in ALLOWED.get(ma, set()):
                problems.append("module %s may not use %s: %s -> %s (%s)"
                                % (ma, mb, a, b, ", ".join(sorted(syms)[:4])))
    for a, targets in sorted(graph.items()):
        for b, syms in sorted(targets.items()):
            la, lb = layer_of(a), layer_of(b)
            if la is not None and lb is not None and lb > la:
                problems.append("renderer/%s/ may not use renderer/%s/ (a higher layer): %s -> %s (%s)"
                                % (RENDERER_LAYERS[la], RENDERER_LAYERS[lb], a, b,
                                   ", ".join(sorted(syms)[:4])))
    return problems


def layer_of(unit):
    """Index of a renderer/ unit's folder in RENDERER_LAYERS; None outside renderer/ (or for a
    folder the list does not name, which check_layers_known reports)."""
    parts = unit.split("/")
    if parts[0] != "renderer" or len(parts) < 3 or parts[1] not in RENDERER_LAYERS:
        return None
    return RENDERER_LAYERS.index(parts[1])


def check_layers_known(units):
    problems = []
    for u in sorted(units):
        parts = u.split("/")
        if parts[0] == "renderer" and (len(parts) < 3 or parts[1] not in RENDERER_LAYERS):
            problems.append("%s: renderer/ code lives in one of the layer folders (%s)"
                            % (u, ", ".join(RENDERER_LAYERS)))
    return problems


def check_names(root):
    problems = []
    for mod in MODULES:
        seen = {}
        for dirpath, dirs, files in os.walk(os.path.join(root, mod)):
            dirs.sort()
            for f in sorted(files):
                if f.endswith((".c", ".cpp")):
                    stem = os.path.splitext(f)[0]
                    rel = os.path.relpath(os.path.join(dirpath, f), root)
                    if stem in seen:
                        problems.append("%s and %s: one library, one object name (%s.o)"
                                        % (seen[stem], rel, stem))
                    seen.setdefault(stem, rel)
    return problems


def check_sizes(root):
    problems = []
    for mod in MODULES:
        for dirpath, _, files in os.walk(os.path.join(root, mod)):
            for f in sorted(files):
                path = os.path.join(dirpath, f)
                rel = os.path.relpath(path, root)
                if not f.endswith((".c", ".cpp", ".h")):
                    continue
                with open(path, encoding="utf-8", errors="replace") as fh:
                    n = sum(1 for _ in fh)
                if f.endswith(".h"):
                    if rel not in PUBLIC_HEADERS and n > MAX_INTERNAL_HEADER_LINES:
                        problems.append("%s: %d lines (an internal header holds at most %d)"
                                        % (rel, n, MAX_INTERNAL_HEADER_LINES))
                elif n > MAX_SOURCE_LINES:
                    problems.append("%s: %d lines (a library source file holds at most %d)"
                                    % (rel, n, MAX_SOURCE_LINES))
    return problems


def unit_name(build, obj):
    """build/renderer/scene/load.o -> renderer/scene/load (the source's path without suffix)."""
    return os.path.splitext(os.path.relpath(obj, build))[0]


def objects(build, root):
    """The object files of the libraries whose source still exists (a moved or deleted source
    leaves its old object in the build folder; it is not part of the build)."""
    out = []
    for mod in MODULES:
        for dirpath, _, files in os.walk(os.path.join(build, mod)):
            for f in files:
                if not f.endswith(".o"):
                    continue
                obj = os.path.join(dirpath, f)
                src = os.path.join(root, os.path.splitext(os.path.relpath(obj, build))[0])
                if os.path.exists(src + ".c") or os.path.exists(src + ".cpp"):
                    out.append(obj)
    return sorted(out)


def self_test():
    """The checker must find a planted cycle, a planted upward use between modules and between
    renderer/ layers, and a file outside the layer folders, and pass clean graphs."""
    clean = {
        "renderer/a": ({"ra"}, {"rb", "sh_x"}),
        "renderer/b": ({"rb"}, {"pm_y"}),
        "sh/x": ({"sh_x"}, {"pm_y"}),
        "photonmap/y": ({"pm_y"}, set()),
    }
    assert check_graph(clean) == [], check_graph(clean)
    cyc = dict(clean)
    cyc["renderer/b"] = ({"rb"}, {"pm_y", "rc"})
    cyc["renderer/c"] = ({"rc"}, {"ra"})
    p = check_graph(cyc)
    assert len(p) == 1 and "cycle among 3 files" in p[0], p
    up = dict(clean)
    up["photonmap/y"] = ({"pm_y"}, {"sh_x"})
    p = check_graph(up)
    assert any("module photonmap may not use sh" in x for x in p), p
    assert any("cycle" in x for x in p), p   # photonmap/y <-> sh/x is also a cycle
    down = dict(clean)
    down["renderer/scene/q"] = ({"rd_q"}, set())
    down["renderer/transport/t"] = ({"rd_t"}, {"rd_q"})
    assert check_graph(down) == [], check_graph(down)
    upward = dict(down)
    upward["renderer/transport/t"] = ({"rd_t"}, {"rd_q", "rd_i"})
    upward["renderer/integrators/i"] = ({"rd_i"}, set())
    upward["renderer/scene/q"] = ({"rd_q"}, {"rd_i"})
    p = check_graph(upward)
    assert len(p) == 2 and all("may not use renderer/integrators/" in x for x in p), p
    assert check_layers_known({"renderer/x.c": 0, "renderer/misc/y": 0}) and \
        not check_layers_known({"renderer/cli/main": 0})
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        for sub in ("renderer/a", "renderer/b", "sh"):
            os.makedirs(os.path.join(tmp, sub))
        for f in ("renderer/a/x.c", "renderer/b/y.c", "sh/x.c"):
            open(os.path.join(tmp, f), "w").close()
        assert check_names(tmp) == [], check_names(tmp)
        open(os.path.join(tmp, "renderer/b/x.cpp"), "w").close()
        p = check_names(tmp)
        assert len(p) == 1 and "renderer/a/x.c and renderer/b/x.cpp" in p[0], p
    print("check_structure self-test: 8 passed, 0 failed")
    return 0


def main(argv):
    if len(argv) == 2 and argv[1] == "--self-test":
        return self_test()
    if len(argv) != 2:
        print("usage: check_structure.py BUILD_DIR | --self-test", file=sys.stderr)
        return 2
    build = argv[1]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    objs = objects(build, root)
    if not objs:
        print("check_structure: %s: no object files (build first)" % build, file=sys.stderr)
        return 2
    tables = {unit_name(build, o): read_symbols(o) for o in objs}
    problems = check_graph(tables) + check_layers_known(tables) + check_names(root) + check_sizes(root)
    for p in problems:
        print("check_structure: " + p)
    print("check_structure: %d objects, %d problem(s)" % (len(objs), len(problems)))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
