"""What `mavctl flash` puts on a board: the profile read (boards/NAME.py), the part of the
stack its SERVICES use (../stack_files.py, as the freezing manifest) and the modules the
profile imports, compiled to .mpy with mpy-cross for the board's CPU (the dialect cut
down with --messages), main.py and board.py beside them. Every refusal is a FlashError:
one line and mavctl's exit status. Reference: docs/mavctl.md.
"""
import ast
import os
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

from mavctl import HOST_TOOLS, ROOT
from mavctl.errors import EXIT_USAGE

if HOST_TOOLS not in sys.path:  # stack_files.py lies beside the package: the manifest uses it too
    sys.path.insert(0, HOST_TOOLS)
import stack_files  # noqa: E402

FIRMWARE = os.path.join(ROOT, "firmware")
STACK = os.path.join(FIRMWARE, "mavstack")
BOARDS = os.path.join(ROOT, "boards")
BIN = os.path.dirname(os.path.abspath(sys.executable))

# -march per board CPU: RP2040 Cortex-M0+, ESP32 Xtensa LX6 (windowed ABI),
# STM32F405 Cortex-M4F (single-precision FPU). The unix vehicle runs on this machine.
ARCH = {"pico": "armv6m", "esp32": "xtensawin", "pyboard": "armv7emsp", "unix": "host"}
# sys.implementation._mpy >> 10 -> mpy-cross -march name (py/persistentcode.h).
ARCH_BY_INDEX = (None, "x86", "x64", "armv6", "armv6m", "armv7m", "armv7em", "armv7emsp",
                 "armv7emdp", "xtensa", "xtensawin", "rv32imc", "rv64imc")
MPY_VERSION = 6
MPY_SUB_VERSION = 3
NATIVE_MODULES = stack_files.NATIVE_MODULES  # hold @micropython.viper code
_CONST = re.compile(r"^_?([A-Z][A-Z0-9_]*)\s*=\s*const\((\d+)\)", re.M)


class FlashError(Exception):
    """One line for the user, and mavctl's exit status for it (errors.py)."""

    def __init__(self, message, status=EXIT_USAGE):
        Exception.__init__(self, message)
        self.status = status


def tool(name):
    """A console script installed beside this interpreter (the project's .venv)."""
    path = os.path.join(BIN, name)
    if not os.path.exists(path):
        path = os.path.join(ROOT, ".venv", "bin", name)
    if not os.path.exists(path):
        raise FlashError("%s not found (run `make setup`)" % name)
    return path


# --- what goes on the board -------------------------------------------------------

def read_profile(board):
    """(profile path, module-level settings (stack_files.profile), names the profile's
    functions import)."""
    path = os.path.join(BOARDS, board + ".py")
    if not os.path.isfile(path):
        known = sorted(f[:-3] for f in os.listdir(BOARDS) if f.endswith(".py"))
        raise FlashError("no board profile %r (boards/: %s)" % (board, ", ".join(known)))
    return path, stack_files.profile(board, BOARDS), module_imports(path)


def module_imports(path):
    """Top-level module names a source file imports, anywhere in it."""
    with open(path, encoding="utf-8") as f:
        tree = ast.parse(f.read(), path)
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module.split(".")[0])
    return names


def local_imports(names):
    """[(source, tree path)] of the modules from firmware/ or boards/ that the profile
    needs beside the stack (the simulator and the parameter table on unix), and theirs."""
    found = {}
    todo = sorted(names)
    while todo:
        name = todo.pop()
        if name in found or name in ("main", "board", "mavstack"):
            continue
        for folder in (FIRMWARE, BOARDS):
            path = os.path.join(folder, name + ".py")
            package = os.path.join(folder, name)
            if os.path.isfile(path):
                found[name] = path
                todo.extend(sorted(module_imports(path)))
                break
            if os.path.isfile(os.path.join(package, "__init__.py")):  # a package: all of it
                for module in sorted(f[:-3] for f in os.listdir(package) if f.endswith(".py")):
                    path = os.path.join(package, module + ".py")
                    found[name + "/" + module] = path
                    todo.extend(sorted(module_imports(path)))
                break
    return [(found[name], name) for name in sorted(found)]


def stack_sources(services, dialect, roots, with_meta, native):
    """[(source path, path in the tree without extension)] of the stack's modules for a
    board with these services and dialect (stack_files.stack_modules; roots: the files
    whose imports count too: main.py, the profile, the modules it imports)."""
    try:
        rels = stack_files.stack_modules(services, dialect, roots, native, with_meta)
    except ValueError as e:
        raise FlashError(str(e))
    return [(os.path.join(FIRMWARE, rel), rel[:-3]) for rel in rels]


def referenced_messages(sources, names):
    """Message ids the modules name: `_X = const(n)` or `_MSG_X = const(n)` where X ends
    the name of message n (`_ATTITUDE = const(30)`, `_MSG_ITEM = const(39)`)."""
    ids = {0}  # HEARTBEAT
    for src, _ in sources:
        with open(src, encoding="utf-8") as f:
            for name, n in _CONST.findall(f.read()):
                full = names.get(int(n), "")
                if name.startswith("MSG_") and name[4:]:
                    name = name[4:]
                if full == name or full.endswith("_" + name):
                    ids.add(int(n))
    return ids


def trimmed_dialect(dialect, sources, extra, workdir):
    """Write the dialect cut down to the messages the stack uses plus `extra`;
    -> {tree path: generated source}."""
    if HOST_TOOLS not in sys.path:
        sys.path.insert(0, HOST_TOOLS)
    import mavgen  # host_tools/mavgen.py, a script beside the package: loaded only for --messages

    jobs = {name: xml for name, xml, _ in mavgen.committed()}
    if dialect not in jobs:
        raise FlashError("--messages: no XML known for dialect %r" % dialect)
    try:
        names = {m.id: m.name for m in mavgen.load(jobs[dialect])[0]}
        wanted = sorted(referenced_messages(sources, names))
        wanted = [str(i) for i in wanted] + [m for m in extra if m]
        runtime, meta = mavgen.generate(jobs[dialect], dialect, wanted)
    except mavgen.MavgenError as e:
        raise FlashError("--messages: %s" % e)
    kept = sorted(names[int(w)] if w.isdigit() else w.upper() for w in set(wanted))
    print("flash: dialect %s cut to %d messages: %s" % (dialect, len(kept), " ".join(kept)))
    out = {}
    for stem, text in ((dialect, runtime), (dialect + "_meta", meta)):
        path = os.path.join(workdir, stem + ".py")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        out["mavstack/dialects/" + stem] = path
    return out


def mpy_cross(src, dest, source_name, arch, opt):
    cmd = [tool("mpy-cross")]
    if arch:
        cmd.append("-march=" + arch)
    if opt:
        cmd.append("-O%d" % opt)
    cmd += ["-s", source_name, "-o", dest, src]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        # mpy-cross reports like a traceback; keep the place and the error.
        lines = [l.strip() for l in (r.stderr or r.stdout).strip().splitlines()]
        where = [l for l in lines if l.startswith("File ")]
        raise FlashError("mpy-cross: %s%s" % (where[-1] + ": " if where else source_name + ": ",
                                               lines[-1] if lines else "failed"))


def build(board, out, arch=None, with_meta=False, messages=None, opt=0, native=True):
    """Compile the tree for `board` into the empty directory `out` -> [relative paths]."""
    profile, settings, imports = read_profile(board)
    arch = arch or settings.get("MPY_ARCH") or ARCH.get(board)
    if not arch:
        raise FlashError("no CPU known for board %r: give --arch" % board)
    if arch not in ARCH_BY_INDEX + ("host",):
        raise FlashError("unknown --arch %s (mpy-cross knows %s, host)"
                         % (arch, ", ".join(ARCH_BY_INDEX[1:])))
    dialect = settings.get("DIALECT", "common")
    if not os.path.isfile(os.path.join(STACK, "dialects", dialect + ".py")):
        raise FlashError("board %s wants dialect %r: firmware/mavstack/dialects/%s.py missing"
                         % (board, dialect, dialect))
    local = local_imports(imports)
    roots = [os.path.join(FIRMWARE, "main.py"), profile] + [src for src, _ in local]
    if "SERVICES" not in settings:
        raise FlashError("board %s: no SERVICES flash can read (a tuple of service names)" % board)
    sources = stack_sources(settings["SERVICES"], dialect, roots, with_meta, native) + local

    with tempfile.TemporaryDirectory() as work:
        if messages is not None:
            generated = trimmed_dialect(dialect, sources, messages, work)
            sources = [(generated.get(rel, src), rel) for src, rel in sources]
        jobs = []
        for src, rel in sources:
            dest = os.path.join(out, rel + ".mpy")
            os.makedirs(os.path.dirname(dest), exist_ok=True)
            jobs.append((src, dest, rel + ".py", arch, opt))
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
            for f in [pool.submit(mpy_cross, *job) for job in jobs]:
                f.result()
    shutil.copyfile(os.path.join(FIRMWARE, "main.py"), os.path.join(out, "main.py"))
    shutil.copyfile(profile, os.path.join(out, "board.py"))
    return tree_files(out)


def tree_files(top):
    found = []
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames.sort()
        for name in sorted(filenames):
            found.append(os.path.relpath(os.path.join(dirpath, name), top).replace(os.sep, "/"))
    return sorted(found)


def prepare_out(path):
    """An empty build directory; a previous build there is replaced, anything else refused."""
    if os.path.isdir(path) and os.listdir(path):
        names = set(os.listdir(path))
        if not {"main.py", "board.py", "mavstack"} <= names:
            raise FlashError("%s is not empty and holds no earlier build: not touching it" % path)
        shutil.rmtree(path)
    os.makedirs(path, exist_ok=True)
