"""The layout's rules, checked on the source: no import circles, and every hand-written
module short (at most 400 lines) with a short docstring (at most 15 lines).

Imports are read with ast wherever they are (module level, functions, `if` blocks).
A module is a node; `import a.b.c` is an edge to a.b.c alone (its parent packages are
loaded too, but that is no circle); `from P import N` is an edge to P.N when that is a
module, else to P. Each group of files is resolved on the path it runs with.
"""
import ast
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MAX_LINES = 400
MAX_DOC_LINES = 15
SKIP_DIRS = {"__pycache__", "build"}
GENERATED = os.path.join("firmware", "mavstack", "dialects")

# (folders whose every module is checked, folders on its import path, first wins)
GROUPS = (
    (("firmware", "boards"), ("firmware", "boards")),
    (("host_tools",), ("host_tools",)),
    # bench puts tests/ (and mcu/, for bench_mcu) on its path: what it imports there counts.
    (("bench",), ("bench", "tests", "mcu")),
)
SIZE_CHECKED = ("firmware", "host_tools", "bench", "boards", "mcu")


def py_files(folder, generated=True):
    """Every .py under ROOT/folder (caches and builds left out; the generated dialects
    too unless generated)."""
    out = []
    for dirpath, dirnames, filenames in os.walk(os.path.join(ROOT, folder)):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS and not d.startswith("."))
        if not generated and os.path.relpath(dirpath, ROOT).startswith(GENERATED):
            continue
        out += [os.path.join(dirpath, f) for f in sorted(filenames) if f.endswith(".py")]
    return out


def module_index(path_folders):
    """{dotted module name: file} of everything importable from these folders, the
    earlier folder winning a name both have."""
    index = {}
    for folder in path_folders:
        top = os.path.join(ROOT, folder)
        for path in py_files(folder):
            parts = os.path.relpath(path, top)[:-3].split(os.sep)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            if parts and all(p.isidentifier() for p in parts):
                index.setdefault(".".join(parts), path)
    return index


def parse(path):
    with open(path, encoding="utf-8") as f:
        return ast.parse(f.read(), path)


def imported(name, path, tree, index):
    """The modules of index that module `name` (file path) imports, anywhere in it."""
    is_package = os.path.basename(path) == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = longest_known(alias.name, index)
                if target:
                    out.add(target)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module
            for alias in node.names:
                sub = source + "." + alias.name if source else alias.name
                if sub in index:
                    out.add(sub)
                else:
                    target = longest_known(source, index)
                    if target:
                        out.add(target)
    out.discard(name)
    return out


def longest_known(dotted, index):
    parts = dotted.split(".") if dotted else []
    while parts:
        if ".".join(parts) in index:
            return ".".join(parts)
        parts.pop()
    return None


def import_graph(checked, path_folders):
    """{module: set of modules it imports} for the modules under `checked` and every
    module of the path they reach."""
    index = module_index(path_folders)
    names = {path: name for name, path in index.items()}
    todo = [names[p] for f in checked for p in py_files(f) if p in names]
    graph = {}
    while todo:
        name = todo.pop()
        if name in graph:
            continue
        graph[name] = imported(name, index[name], parse(index[name]), index)
        todo += sorted(graph[name] - set(graph))
    return graph


def find_cycle(graph):
    """One import circle as [a, b, ..., a], or None."""
    state = {}
    for start in sorted(graph):
        if state.get(start):
            continue
        stack = [(start, iter(sorted(graph[start])))]
        trail = [start]
        state[start] = 1  # on the trail
        while stack:
            node, edges = stack[-1]
            nxt = next(edges, None)
            if nxt is None:
                state[node] = 2  # done: no circle through it
                stack.pop()
                trail.pop()
            elif state.get(nxt) == 1:
                return trail[trail.index(nxt):] + [nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                stack.append((nxt, iter(sorted(graph.get(nxt, ())))))
                trail.append(nxt)
    return None


def test_no_import_circles():
    circles = []
    for checked, path_folders in GROUPS:
        graph = import_graph(checked, path_folders)
        while True:
            cycle = find_cycle(graph)
            if cycle is None:
                break
            circles.append(" -> ".join(cycle))
            graph[cycle[0]] = graph[cycle[0]] - {cycle[1]}  # look for the next one
    assert not circles, "import circles:\n  " + "\n  ".join(circles)


def test_modules_short_with_short_docstrings():
    long = []
    for folder in SIZE_CHECKED:
        for path in py_files(folder, generated=False):
            rel = os.path.relpath(path, ROOT)
            with open(path, encoding="utf-8") as f:
                text = f.read()
            lines = len(text.splitlines())
            if lines > MAX_LINES:
                long.append("%s: %d lines (at most %d)" % (rel, lines, MAX_LINES))
            doc = ast.get_docstring(ast.parse(text, path)) or ""
            if len(doc.splitlines()) > MAX_DOC_LINES:
                long.append("%s: a docstring of %d lines (at most %d)"
                            % (rel, len(doc.splitlines()), MAX_DOC_LINES))
    assert not long, "\n  ".join(["too long:"] + long)


def test_the_checks_see_circles():
    """find_cycle and the edges it is given, on a made-up package."""
    index = {"p": "p/__init__.py", "p.a": "p/a.py", "p.b": "p/b.py"}
    tree = ast.parse("from . import a\nfrom . import NAME\ndef f():\n    import p.b\n")
    assert imported("p.b", "p/b.py", tree, index) == {"p.a", "p"}
    assert imported("p", "p/__init__.py", ast.parse("from .b import x"), index) == {"p.b"}
    assert find_cycle({"p": {"p.b"}, "p.b": {"p.a", "p"}, "p.a": set()}) == ["p", "p.b", "p"]
    assert find_cycle({"p": {"p.a"}, "p.a": set()}) is None
