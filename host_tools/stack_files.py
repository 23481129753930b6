"""Which of the stack's modules a board carries: its profile's settings read without
running it, and the modules of firmware/mavstack that its services, its dialect, its
profile and main.py import, wherever the import is (so the modules a service loads
lazily come too). The freezing manifest (firmware/manifest.py) and `mavctl flash`
(mavctl/flash_tree.py) both take their lists from here, so that a board that lists
fewer services carries only what it lists. Standard library only.
Reference: docs/boards.md (Heap and flash).
"""
import ast
import os

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
BOARDS = os.path.join(ROOT, "boards")
NATIVE_MODULES = ("bytes_viper.py", "sha256_viper.py", "qemu_viper.py")  # hold @micropython.viper code
# compat.py's stand-ins for what a port lacks, which its imports do not bring: CPython's
# (never on a board) and the qemu port's clock (there when the profile imports it).
STAND_INS = ("mavstack.compat_cpython", "mavstack.qemu")
_OPS = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
        ast.BitOr: lambda a, b: a | b, ast.LShift: lambda a, b: a << b}


class Module:
    """A sibling board module's settings, for `import unix` then `unix.SERVICES`."""

    def __init__(self, settings):
        self.settings = settings


def profile(board, folder=BOARDS):
    """{name: value} of the module-level settings of folder/board.py that can be worked out
    without running it: literals, names and arithmetic of those, and what it takes from
    sibling modules (`from qemu import *`, `import unix` ... `unix.SERVICES`)."""
    path = os.path.join(folder, board + ".py")
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    env = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and not node.level and _sibling(node.module, folder):
            theirs = profile(node.module, folder)
            for alias in node.names:
                if alias.name == "*":
                    env.update((k, v) for k, v in theirs.items() if not k.startswith("_"))
                elif alias.name in theirs:
                    env[alias.asname or alias.name] = theirs[alias.name]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if _sibling(alias.name, folder):
                    env[alias.asname or alias.name] = Module(profile(alias.name, folder))
        elif isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            try:
                env[node.targets[0].id] = _value(node.value, env)
            except ValueError:
                env.pop(node.targets[0].id, None)
    return {k: v for k, v in env.items() if not isinstance(v, Module)}


def _sibling(name, folder):
    return name and "." not in name and os.path.isfile(os.path.join(folder, name + ".py"))


def _value(node, env):
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, (ast.Tuple, ast.List)):
        items = [_value(n, env) for n in node.elts]
        return tuple(items) if isinstance(node, ast.Tuple) else items
    if isinstance(node, ast.Dict) and None not in node.keys:
        return {_value(k, env): _value(v, env) for k, v in zip(node.keys, node.values)}
    if isinstance(node, ast.Name) and node.id in env and not isinstance(env[node.id], Module):
        return env[node.id]
    if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
            and isinstance(env.get(node.value.id), Module) and node.attr in env[node.value.id].settings):
        return env[node.value.id].settings[node.attr]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        return -_value(node.operand, env)
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        try:
            return _OPS[type(node.op)](_value(node.left, env), _value(node.right, env))
        except TypeError:
            raise ValueError("not a setting")
    raise ValueError("not a setting")


def service_names():
    """Every service a board may list (firmware/mavstack/services/: modules and packages)."""
    top = os.path.join(FIRMWARE, "mavstack", "services")
    names = [n[:-3] for n in os.listdir(top) if n.endswith(".py") and n != "__init__.py"]
    names += [n for n in os.listdir(top) if os.path.isfile(os.path.join(top, n, "__init__.py"))]
    return sorted(names)


def stack_modules(services, dialect, roots=(), native=True, meta=False):
    """Sorted paths, relative to firmware/, of the stack's modules for a board with these
    services and this dialect (with its *_meta names and layout if meta): each service's
    module or whole package, what those and the files in roots (main.py, the profile and
    its modules) import, the packages above them; viper modules left out unless native.
    ValueError for a service or dialect the stack does not have."""
    index = _index()
    todo = []
    for name in services:
        base = "mavstack.services." + name
        if base not in index:
            raise ValueError("no service %r (firmware/mavstack/services/: %s)"
                             % (name, ", ".join(service_names())))
        todo += [m for m in index if m == base or m.startswith(base + ".")]
    dialects = [dialect] + ([dialect + "_meta", "layout"] if meta else [])
    for name in dialects:
        if "mavstack.dialects." + name not in index:
            raise ValueError("no dialect module firmware/mavstack/dialects/%s.py" % name)
        todo.append("mavstack.dialects." + name)
    for path in roots:
        todo += imported("", path, index)
    found = set()
    while todo:
        name = todo.pop()
        if name in found or (not native and os.path.basename(index[name]) in NATIVE_MODULES):
            continue
        found.add(name)
        parts = name.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]
        theirs = imported(name, index[name], index)
        if name == "mavstack.compat":
            theirs -= set(STAND_INS)
        todo += sorted(theirs - found)
    return sorted(os.path.relpath(index[m], FIRMWARE).replace(os.sep, "/") for m in found)


def _index():
    """{dotted name: file} of every module of firmware/mavstack."""
    index = {}
    for dirpath, dirnames, filenames in os.walk(os.path.join(FIRMWARE, "mavstack")):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
        for f in filenames:
            if f.endswith(".py"):
                parts = os.path.relpath(os.path.join(dirpath, f), FIRMWARE)[:-3].split(os.sep)
                index[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = os.path.join(dirpath, f)
    return index


def imported(name, path, index):
    """The modules of index that module `name` (its file: path) imports, anywhere in it."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    package = name.split(".") if os.path.basename(path) == "__init__.py" else name.split(".")[:-1]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(_known(a.name, index) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            source = node.module or ""
            if node.level:
                source = ".".join(package[:len(package) - node.level + 1] + ([source] if source else []))
            for alias in node.names:
                sub = source + "." + alias.name if source else alias.name
                out.add(sub if sub in index else _known(source, index))
    out.discard(None)
    out.discard(name)
    return out


def _known(dotted, index):
    """The longest leading part of a dotted name that is a module of index, or None."""
    parts = dotted.split(".") if dotted else []
    while parts and ".".join(parts) not in index:
        parts.pop()
    return ".".join(parts) if parts else None
