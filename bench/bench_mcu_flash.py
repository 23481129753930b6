"""The frozen stack's flash by part, on the emulated boards' firmware (mcu/firmware.py).

  flash_kb_stack_unix_set  firmware/mavstack frozen for the Cortex-M3 with the unix board's
                           services (all but signing), the set a full vehicle runs
  flash_kb_<part>          that stack by part: core (endpoint, wire, kernels, transports,
                           storage), each service, dialect_common; signing from qemu_m3's
  flash_kb_stack_m3/_m0    the stack each emulated board freezes (its own SERVICES)
  flash_kb_board_m3        main.py, the profile and its board modules, frozen beside it
  flash_kb_frozen_unix_set_m3  that firmware image (stack, main.py, board) less the plain one

A part is what its modules put in frozen_content.o, where MicroPython compiles the frozen
modules: the symbols their sections of frozen_content.c define, their strings and qstrs
(shared ones split evenly), checked to add up to the object. Reference: docs/boards.md.
"""
import collections
import os
import re
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
sys.path.insert(0, os.path.join(ROOT, "mcu"))
sys.path.insert(0, os.path.join(ROOT, "host_tools"))

import firmware  # noqa: E402
import stack_files  # noqa: E402

TARGET_KB = 200
QSTR_TABLES = 7  # bytes a frozen qstr costs beside its string: pool pointer 4, hash 2, length 1
UNIX_SET = os.path.join(firmware.BUILD, "unix_set", "unix_set.py")


def module_bytes(build_dir):
    """{frozen file name ('mavstack/link.py'): bytes in frozen_content.o}, parts summing
    to the object's size; checked against it (within 1%)."""
    with open(os.path.join(build_dir, "frozen_content.c")) as f:
        text = f.read()
    obj = os.path.join(build_dir, "frozen_content.o")
    sizes = {}
    for line in subprocess.run(["arm-none-eabi-nm", "-S", obj], capture_output=True, text=True,
                               check=True).stdout.splitlines():
        p = line.split()
        if len(p) == 4:
            sizes[p[3]] = int(p[1], 16)
    qstrs = _frozen_qstrs(text)
    tail = text.index("const char mp_frozen_names[]")
    sections = re.split(r"^// frozen module \S+\n// - original source file: .*\n// - frozen file name: (\S+)\n",
                        text[:tail], flags=re.M)
    own, users = {}, collections.defaultdict(set)
    literal = 0  # gcc numbers compound literals (big ints) in order of appearance
    for name, body in zip(sections[1::2], sections[2::2]):
        defined = set()
        for line in re.findall(r"^(?:static )?const [^=]*", body, re.M):
            defined.update(t for t in re.findall(r"\w+", line) if t in sizes)
        for _ in re.findall(r"\[\]\)\s*\{", body):
            defined.add("__compound_literal.%d" % literal)
            literal += 1
        own[name] = sum(sizes.get(s, 0) for s in defined) + len(name) + 1 + 4  # + its frozen list entry
        for s in re.findall(r'\{\{&mp_type_(?:str|bytes)\}, \d+, \d+, \(const byte\*\)"((?:[^"\\]|\\.)*)"', body):
            users[_c_string(s)].add(name)
        for q in set(re.findall(r"\bMP_QSTR_\w+", body)) & set(qstrs):
            users[q].add(name)
    # A string is stored once however many modules use it (gcc merges equal ones).
    shared = collections.defaultdict(set)
    for key, names in users.items():
        shared[qstrs.get(key, key)] |= names
        if key in qstrs:
            for name in names:
                own[name] += QSTR_TABLES / len(names)
    for s, names in shared.items():
        for name in names:
            own[name] += (len(s) + 1) / len(names)
    total = sum(own.values())
    size = _object_size(obj)
    if abs(total - size) > size / 100:
        raise RuntimeError("frozen_content.o holds %d bytes; its modules add up to %d" % (size, total))
    return own


def _object_size(obj):
    out = subprocess.run(["arm-none-eabi-size", obj], capture_output=True, text=True, check=True).stdout
    text, data = out.splitlines()[1].split()[:2]
    return int(text) + int(data)


def _frozen_qstrs(text):
    """{MP_QSTR_ name: its string} of the qstrs frozen_content.c adds to the firmware's."""
    start = text.index("enum {")
    names = re.findall(r"^\s+(MP_QSTR_\w+)(?: = MP_QSTRnumber_of)?,$", text[start:text.index("};", start)], re.M)
    pool = text[text.index("const qstr_pool_t mp_qstr_frozen_const_pool"):]
    strings = re.findall(r'^\s+"((?:[^"\\]|\\.)*)",$', pool[:pool.index("};")], re.M)
    if len(names) != len(strings):
        raise RuntimeError("frozen_content.c: %d qstr names, %d strings" % (len(names), len(strings)))
    return dict(zip(names, (_c_string(s) for s in strings)))


def _c_string(s):
    return s.encode("latin1").decode("unicode_escape").encode("latin1")


def parts(sizes, services, dialect="common"):
    """{part: bytes} of the stack's modules in sizes: a service's own modules and those
    only it imports (signing: the SHA-256 kernels) are its part, dialects/NAME.py is
    dialect_NAME, the rest is core."""
    closures = {s: set(stack_files.stack_modules([s], dialect)) for s in services}
    out = collections.Counter()
    for name, n in sizes.items():
        path = name.split("/")
        if path[0] != "mavstack":
            continue
        if path[1:2] == ["services"] and len(path) > 2 and path[2] != "__init__.py":
            part = path[2][:-3] if path[2].endswith(".py") else path[2]
        elif path[1:2] == ["dialects"] and path[2] != "__init__.py":
            part = "dialect_" + path[2][:-3]
        else:
            users = [s for s in services if name in closures[s]]
            part = users[0] if len(users) == 1 and len(services) > 1 else "core"
        out[part] += n
    return out


def unix_set_manifest():
    """A manifest freezing qemu_m3's firmware with the unix board's services."""
    services = stack_files.profile("unix")["SERVICES"]
    text = ("# bench/bench_mcu_flash.py: the qemu_m3 firmware with the unix board's services\n"
            "include(%r, services=%r)\n" % (os.path.join(ROOT, "firmware", "manifest.py"), ",".join(services)))
    os.makedirs(os.path.dirname(UNIX_SET), exist_ok=True)
    if not os.path.exists(UNIX_SET) or open(UNIX_SET).read() != text:
        with open(UNIX_SET, "w") as f:
            f.write(text)
    return services


def _kb(n):
    return round(n / 1024, 1)


def run():
    if firmware.tools_missing():
        raise RuntimeError("MCU tools missing (make mcu-deps): %s" % firmware.tools_missing())
    out = {}
    services = unix_set_manifest()
    elf = firmware.build("qemu_m3", manifest=UNIX_SET)
    sizes = module_bytes(firmware.build_dir("qemu_m3", manifest=UNIX_SET))
    out["flash_kb_stack_unix_set"] = _kb(sum(n for m, n in sizes.items() if m.startswith("mavstack/")))
    for part, n in sorted(parts(sizes, services).items()):
        out["flash_kb_" + part] = _kb(n)
    out["flash_kb_frozen_unix_set_m3"] = round(
        firmware.flash_kb(elf) - firmware.flash_kb(firmware.build("qemu_m3", frozen=False)), 1)
    for board, tag in (("qemu_m3", "m3"), ("qemu_m0", "m0")):
        firmware.build(board)
        sizes = module_bytes(firmware.build_dir(board))
        out["flash_kb_stack_" + tag] = _kb(sum(n for m, n in sizes.items() if m.startswith("mavstack/")))
        if tag == "m3":
            out["flash_kb_board_m3"] = _kb(sum(n for m, n in sizes.items() if not m.startswith("mavstack/")))
            board_parts = parts(sizes, stack_files.profile(board)["SERVICES"])
            out["flash_kb_signing"] = _kb(board_parts["signing"])
    return out


def floors(r):
    return [("frozen stack with the unix board's services under %d KB" % TARGET_KB,
             r["flash_kb_stack_unix_set"] < TARGET_KB)]
