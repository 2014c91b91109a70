#!/usr/bin/python3
"""The include graph of src/ and include/ against the layers of docs/layers.md.

    check_layers.py SOURCE_DIR      check the tree (exit 1 on a violation)
    check_layers.py --self-test     check this checker on synthetic trees

Every `#include "..."` of a file under src/ or include/ is resolved to a file of the tree
("subslip/x/y.hpp" under include/, anything else relative to the including file first). A file's
layer is its directory: include/subslip/<layer>/... and src/<layer>/...; the one header directly
under include/subslip/, material_point.hpp, is the layer `point`. Fails on
  - an include from a lower layer up to a higher one, or between two layers of the same level;
  - a circle of includes among files (each circle reported once, as the files it passes);
  - a quoted include that names no file of the tree, or a file that belongs to no layer.
Standard library only.
"""

import os
import re
import sys
import tempfile

# Low to high; the layers of one level are independent of each other. A file may include files
# of its own layer and of layers of a lower level (docs/layers.md says why each sits where).
LEVELS = [
    ("parallel", "integrators"),  # ranks and collectives; step control, extrapolation, roots
    ("law",),                     # the subloading-overstress law (uses the scalar root finder)
    ("contact", "crystal"),       # the physics: a contact point, grains and the Taylor aggregate
    ("point",),                   # the material-point API over the physics
    ("history", "fe"),            # a contact point driven along a history; the FE entry points
    ("study",),                   # accuracy, robustness and benchmark studies (and their peers)
    ("calibration",),             # the law fitted to measured curves (bounded least squares)
    ("model",),                   # the plain run model a scene becomes (cases, fields, units)
    ("driver",),                  # runs a model's cases, hands results to sinks it defines
    ("io",),                      # scene parsers into the model; HDF5 sinks; result files
    ("cli",),                     # arguments and printing; `subslip run` (cli/run_scene.hpp)
    ("python",),                  # the Python module: runs as `subslip run`, material points
]
LEVEL = {layer: k for k, layers in enumerate(LEVELS) for layer in layers}

# Top-level public headers (include/subslip/<name>) and their layers.
TOP_LEVEL_HEADERS = {"material_point.hpp": "point"}

# Known violations still in the tree: (including file, included file, reason), paths relative to
# the source directory. A violation not listed fails; a listed one that is gone fails too, so
# that the list only shrinks.
ALLOWED = []

SOURCE_SUFFIXES = (".hpp", ".cpp", ".h", ".cc", ".hh", ".ipp", ".inl")
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def layer_of(rel):
    """The layer of a file (path relative to the source directory, '/' separators), or None."""
    parts = rel.split("/")
    if parts[0] == "include" and len(parts) >= 3 and parts[1] == "subslip":
        if len(parts) == 3:
            return TOP_LEVEL_HEADERS.get(parts[2])
        return parts[2] if parts[2] in LEVEL else None
    if parts[0] == "src" and len(parts) >= 3:
        return parts[1] if parts[1] in LEVEL else None
    return None


def source_files(root):
    files = []
    for top in ("src", "include"):
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
            dirnames.sort()
            for name in sorted(filenames):
                if name.endswith(SOURCE_SUFFIXES):
                    full = os.path.join(dirpath, name)
                    files.append(os.path.relpath(full, root).replace(os.sep, "/"))
    return files


def resolve(root, including, target):
    """The file (relative to root) that `#include "target"` in `including` names, or None."""
    candidates = []
    if not target.startswith("subslip/"):
        candidates.append(os.path.join(os.path.dirname(including), target))
    candidates.append(os.path.join("include", target))
    for c in candidates:
        rel = os.path.normpath(c).replace(os.sep, "/")
        if not rel.startswith("../") and os.path.isfile(os.path.join(root, rel)):
            return rel
    return None


def include_graph(root, files, problems):
    """{file: [(line, included file)]}; unresolvable includes are added to `problems`."""
    graph = {}
    for rel in files:
        edges = []
        with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
            for number, text in enumerate(f, start=1):
                m = INCLUDE.match(text)
                if not m:
                    continue
                target = resolve(root, rel, m.group(1))
                if target is None:
                    problems.append(f'{rel}:{number}: #include "{m.group(1)}" names no file '
                                    "under src/ or include/")
                else:
                    edges.append((number, target))
        graph[rel] = edges
    return graph


def cycles(graph):
    """Every circle of includes: one list of files per strongly connected component of more than
    one file (or a file that includes itself), each a closed path through the component."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = [0]

    def strongconnect(v):  # Tarjan, iterative (no recursion limit on long include chains)
        work = [(v, iter(graph.get(v, [])))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        while work:
            node, edges = work[-1]
            advanced = False
            for _, w in edges:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(graph.get(w, []))))
                    advanced = True
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == node:
                        break
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            strongconnect(v)

    found = []
    for component in components:
        members = set(component)
        start = min(component)
        if len(component) == 1 and all(t != start for _, t in graph.get(start, [])):
            continue
        # A shortest path from `start` back to itself inside the component (breadth first).
        previous = {start: None}
        queue, end = [start], None
        while queue and end is None:
            nxt = []
            for v in queue:
                for _, w in graph.get(v, []):
                    if w == start:
                        end = v
                        break
                    if w in members and w not in previous:
                        previous[w] = v
                        nxt.append(w)
                if end is not None:
                    break
            queue = nxt
        path = [end]
        while previous[path[-1]] is not None:
            path.append(previous[path[-1]])
        path.reverse()
        found.append((path + [start], sorted(component)))
    return found


def check(root, allowed=None, out=sys.stdout):
    """Prints every violation in the tree at `root`; returns the number of them."""
    allowed = ALLOWED if allowed is None else allowed
    problems = []
    files = source_files(root)
    graph = include_graph(root, files, problems)
    for rel in files:
        if layer_of(rel) is None:
            problems.append(f"{rel}: belongs to no layer (add its directory to LEVELS in "
                            "tests/check_layers.py and to docs/layers.md)")
    allowed_pairs = {(a, b): why for a, b, why in allowed}
    used = set()
    for rel in files:
        lower = layer_of(rel)
        for number, target in graph[rel]:
            upper = layer_of(target)
            if lower is None or upper is None or lower == upper or LEVEL[upper] < LEVEL[lower]:
                continue
            if (rel, target) in allowed_pairs:
                used.add((rel, target))
                continue
            how = "up to" if LEVEL[upper] > LEVEL[lower] else "sideways to"
            problems.append(f"{rel}:{number}: includes {target}: layer '{lower}' {how} "
                            f"'{upper}'")
    for pair in sorted(set(allowed_pairs) - used):
        problems.append(f"{pair[0]}: the allowed include of {pair[1]} is gone; remove it from "
                        "ALLOWED in tests/check_layers.py")
    for path, component in cycles(graph):
        steps = []
        for a, b in zip(path, path[1:]):
            line = next(n for n, t in graph[a] if t == b)
            steps.append(f"{a}:{line}")
        problems.append("include circle: " + " -> ".join(steps) + f" -> {path[-1]}"
                        + (f" ({len(component)} files in the circles: "
                           + ", ".join(component) + ")" if len(component) > len(path) - 1
                           else ""))
    for p in problems:
        print(p, file=out)
    if not problems:
        edges = sum(len(e) for e in graph.values())
        known = f" but the {len(used)} allowed in ALLOWED" if used else ""
        print(f"include layers: {len(files)} files, {edges} includes, no circle, none up the "
              f"layers{known}", file=out)
    return len(problems)


def self_test():
    """The checker fails on each kind of violation and passes a clean tree."""
    import io as text_io

    def tree(files):
        root = tempfile.mkdtemp(prefix="check_layers_")
        for rel, text in files.items():
            path = os.path.join(root, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return root

    def run(files, allowed=()):
        out = text_io.StringIO()
        count = check(tree(files), list(allowed), out)
        return count, out.getvalue()

    clean = {
        "include/subslip/parallel/team.hpp": "#pragma once\n",
        "include/subslip/crystal/grain.hpp": '#include "subslip/parallel/team.hpp"\n',
        "src/crystal/grain.cpp": '#include "subslip/crystal/grain.hpp"\n#include "detail.hpp"\n',
        "src/crystal/detail.hpp": "#include <vector>\n// #include \"subslip/cli/x.hpp\"\n",
        "include/subslip/material_point.hpp": '#include "subslip/crystal/grain.hpp"\n',
        "src/cli/main.cpp": '#include "subslip/material_point.hpp"\n'
                            '#include "../crystal/detail.hpp"\n',
    }
    failures = []

    def expect(name, files, want_fail, *needles, allowed=()):
        count, text = run(files, allowed)
        if (count > 0) != want_fail or any(n not in text for n in needles):
            failures.append(f"{name}: {count} problems, expected "
                            f"{'some' if want_fail else 'none'} naming {needles}:\n{text}")

    expect("clean tree", clean, False)
    upward = dict(clean)
    upward["include/subslip/crystal/grain.hpp"] += '#include "subslip/driver/run.hpp"\n'
    upward["include/subslip/driver/run.hpp"] = "#pragma once\n"
    expect("upward include", upward, True,
           "include/subslip/crystal/grain.hpp:2: includes include/subslip/driver/run.hpp: "
           "layer 'crystal' up to 'driver'")
    expect("allowed upward include", upward, False,
           allowed=[("include/subslip/crystal/grain.hpp", "include/subslip/driver/run.hpp",
                     "test")])
    expect("stale allowance", clean, True, "is gone",
           allowed=[("include/subslip/crystal/grain.hpp", "include/subslip/driver/run.hpp",
                     "test")])
    sideways = dict(clean)
    sideways["src/crystal/detail.hpp"] += '#include "subslip/contact/point.hpp"\n'
    sideways["include/subslip/contact/point.hpp"] = "#pragma once\n"
    expect("sideways include", sideways, True, "layer 'crystal' sideways to 'contact'")
    relative_up = dict(clean)
    relative_up["src/crystal/detail.hpp"] += '#include "../io/parse.hpp"\n'
    relative_up["src/io/parse.hpp"] = "#pragma once\n"
    expect("relative include up", relative_up, True,
           "src/crystal/detail.hpp:3: includes src/io/parse.hpp: layer 'crystal' up to 'io'")
    circle = dict(clean)
    circle["src/crystal/a.hpp"] = '#include "b.hpp"\n'
    circle["src/crystal/b.hpp"] = '\n#include "subslip/crystal/c.hpp"\n'
    circle["include/subslip/crystal/c.hpp"] = '#include "../../../src/crystal/a.hpp"\n'
    expect("circle within a layer", circle, True,
           "include circle: include/subslip/crystal/c.hpp:1 -> src/crystal/a.hpp:1 -> "
           "src/crystal/b.hpp:2 -> include/subslip/crystal/c.hpp")
    itself = dict(clean)
    itself["src/crystal/self.hpp"] = '#include "self.hpp"\n'
    expect("file including itself", itself, True, "include circle: src/crystal/self.hpp:1")
    unresolved = dict(clean)
    unresolved["src/crystal/grain.cpp"] += '#include "subslip/crystal/missing.hpp"\n'
    expect("unresolved include", unresolved, True, "names no file")
    stray = dict(clean)
    stray["src/extra/thing.cpp"] = "\n"
    expect("file in no layer", stray, True, "src/extra/thing.cpp: belongs to no layer")
    for f in failures:
        print("self-test failed: " + f)
    if not failures:
        print("check_layers self-test: every violation is found, a clean tree passes")
    return 1 if failures else 0


def main(argv):
    if len(argv) == 2 and argv[1] == "--self-test":
        return self_test()
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    return 1 if check(argv[1]) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
