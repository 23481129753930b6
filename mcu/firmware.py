"""The emulated microcontrollers: MicroPython's qemu port built with mavstack frozen in,
and run under qemu-system-arm with its UARTs on ptys.

    python mcu/firmware.py build [qemu_m3|qemu_m0 ...] [--heap-kb N]   build the firmware
    python mcu/firmware.py repl qemu_m3                                 a REPL on the board
    python mcu/firmware.py run qemu_m3                                  the board with a
        filesystem (mcu/boot_fs.py), its UARTs on ptys: `mavctl flash --board qemu_m3` target

MicroPython's source is Debian's source package `micropython` (1.25.0 in trixie), fetched
with `apt-get source` into build/mcu/; the toolchain and emulator are Debian's too (`make
mcu-deps`). The boards, qemu_m3 (Cortex-M3, viper kernels, MAVLink on UART1) and qemu_m0
(Cortex-M0, portable kernels, one UART), are profiles in boards/; their reference:
docs/boards.md, the MCU stage: docs/testing.md.
"""
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.join(ROOT, "build", "mcu")
SUITE = "trixie"  # the Debian suite whose source package we build (micropython 1.25.0)
VERSION = "1.25.0"
PACKAGE = "micropython=1.25.0+ds-1"  # pinned: the exact Debian source package
DEFAULT_HEAP_KB = 60  # the whole vehicle's smallest (min_heap_kb_m3/_m0): the tests run in it
FS_HEAP_KB = 512  # the firmware with a filesystem: the stack's code is loaded into the heap

# board profile -> (qemu port BOARD, qemu machine arguments, frozen viper kernels?)
BOARDS = {
    "qemu_m3": ("MPS2_AN385", ["-machine", "mps2-an385"], True),
    "qemu_m0": ("MICROBIT", ["-machine", "microbit", "-global", "nrf51-soc.flash-size=1048576",
                             "-global", "nrf51-soc.sram-size=262144"], False),
}
# The same machine and build, another profile: the Cortex-M0 as a distance-sensor peripheral.
BOARDS["qemu_m0_rangefinder"] = ("MICROBIT",) + BOARDS["qemu_m0"][1:]


def _sh(cmd, **kw):
    kw.setdefault("check", True)
    return subprocess.run(cmd, **kw)


def tools_missing():
    """What the stage needs and this machine lacks (empty: all there)."""
    need = ("arm-none-eabi-gcc", "qemu-system-arm")
    missing = [t for t in need if shutil.which(t) is None]
    if not os.path.exists("/usr/lib/arm-none-eabi/newlib") and not os.path.exists("/usr/lib/arm-none-eabi/lib"):
        missing.append("libnewlib-arm-none-eabi")
    return missing


def _deb_src_entry():
    """A deb-src entry for SUITE built from the machine's own Debian apt entries."""
    sources = "/etc/apt/sources.list.d/debian.sources"
    if os.path.exists(sources):
        text = open(sources).read()
        for stanza in text.split("\n\n"):
            uri = re.search(r"^URIs:\s*(\S+)", stanza, re.M)
            if uri and "security" not in uri.group(1):
                key = re.search(r"^Signed-By:\s*(\S+)", stanza, re.M)
                return ("Types: deb-src\nURIs: %s\nSuites: %s\nComponents: main\n%s"
                        % (uri.group(1), SUITE, "Signed-By: %s\n" % key.group(1) if key else ""))
    for line in open("/etc/apt/sources.list") if os.path.exists("/etc/apt/sources.list") else ():
        words = line.split()
        if len(words) >= 3 and words[0] == "deb" and "security" not in words[1]:
            uri = words[2] if words[1].startswith("[") else words[1]
            return "Types: deb-src\nURIs: %s\nSuites: %s\nComponents: main\n" % (uri, SUITE)
    raise SystemExit("mcu: no Debian apt entry on this machine to fetch MicroPython's source from")


def source_dir():
    """MicroPython's source tree, fetched once."""
    src = os.path.join(BUILD, "src", "micropython-" + VERSION)
    if os.path.exists(os.path.join(src, "ports", "qemu", "Makefile")):
        return src
    apt = os.path.join(BUILD, "apt")
    for d in ("parts", "lists/partial", "cache/archives/partial"):
        os.makedirs(os.path.join(apt, d), exist_ok=True)
    with open(os.path.join(apt, "parts", "micropython-src.sources"), "w") as f:
        f.write(_deb_src_entry())
    # A private apt state: the machine's own lists and sources stay as they are.
    opts = ["-o", "Dir::Etc::SourceList=/dev/null", "-o", "Dir::Etc::SourceParts=" + apt + "/parts",
            "-o", "Dir::State::Lists=" + apt + "/lists", "-o", "Dir::Cache=" + apt + "/cache",
            "-o", "APT::Sandbox::User=root"]
    _sh(["apt-get", "-q"] + opts + ["update"], stdout=subprocess.DEVNULL)
    dl = os.path.join(BUILD, "src")
    os.makedirs(dl, exist_ok=True)
    _sh(["apt-get", "-q"] + opts + ["source", "--download-only", PACKAGE], cwd=dl,
        stdout=subprocess.DEVNULL)
    orig = [n for n in os.listdir(dl) if n.startswith("micropython_" + VERSION) and ".orig.tar" in n]
    if not orig:
        raise SystemExit("mcu: apt-get source gave no micropython %s tarball" % VERSION)
    _sh(["tar", "xf", orig[0]], cwd=dl)
    # The +ds tarball leaves out micropython-lib; the build only checks it is there.
    lib = os.path.join(src, "lib", "micropython-lib")
    os.makedirs(lib, exist_ok=True)
    open(os.path.join(lib, "README.md"), "a").close()
    return src


def elf_path(board, heap_kb=DEFAULT_HEAP_KB, frozen=True):
    return os.path.join(BUILD, "%s-%dk%s.elf" % (board, heap_kb, "" if frozen else "-plain"))


def build(board, heap_kb=DEFAULT_HEAP_KB, frozen=True, manifest=None, quiet=True):
    """Build the firmware for a board profile -> path of its ELF (cached by heap size).

    frozen=False builds the plain firmware (nothing frozen), for the flash figure;
    manifest overrides firmware/manifest.py (tests freeze their scripts in as well).
    One build at a time (a lock file): test processes may ask at once.
    """
    return _locked(_build, board, heap_kb, frozen, manifest, quiet)


def build_with_filesystem(board, heap_kb=FS_HEAP_KB, quiet=True):
    """The firmware `mavctl flash` writes to: MicroPython with littlefs and the frozen
    mcu/boot_fs.py, which mounts a filesystem over the profile's FS_REGION at /flash, and
    runs main.py from it after a soft reset to the REPL -> path of its ELF. Nothing of
    mavstack is frozen in: the stack comes as the .mpy tree flash copies, and its code
    then lives in the heap, hence the larger one."""
    return _locked(_build, board, heap_kb, True, _boot_manifest(board), quiet, filesystem=True)


def _locked(fn, *args, **kw):
    import fcntl

    os.makedirs(BUILD, exist_ok=True)
    with open(os.path.join(BUILD, ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return fn(*args, **kw)


def _build(board, heap_kb, frozen, manifest, quiet, filesystem=False):
    port_board, _machine, native = BOARDS[board]
    out = elf_path(board, heap_kb, frozen)
    if manifest is not None:
        out = out[:-4] + "-" + os.path.basename(os.path.dirname(manifest)) + ".elf"
    src = source_dir()
    _patch_boot(src)
    if filesystem:
        out = elf_path(board, heap_kb)[:-4] + "-fs.elf"
    bdir = build_dir(board, frozen, manifest, filesystem)
    inputs = (_boot_inputs(board) if filesystem else _manifest_inputs(manifest)) if frozen else []
    if os.path.exists(out) and all(os.path.getmtime(p) <= os.path.getmtime(out) for p in inputs):
        return out
    # The heap size is a compile-time constant of main.c: rebuild that object when it changes.
    stamp = os.path.join(bdir, "heap_kb")
    if os.path.exists(stamp) and open(stamp).read() != str(heap_kb):
        for obj in ("main.o", "main.P"):
            if os.path.exists(os.path.join(bdir, obj)):
                os.remove(os.path.join(bdir, obj))
    os.makedirs(bdir, exist_ok=True)
    with open(stamp, "w") as f:
        f.write(str(heap_kb))
    if not os.path.exists(os.path.join(src, "mpy-cross", "build", "mpy-cross")):
        # Built on its own first: the port's make would pass our BUILD= down to it.
        _sh(["make", "-C", os.path.join(src, "mpy-cross"), "-j%d" % (os.cpu_count() or 2)],
            capture_output=quiet)
    env = dict(os.environ, MAVSTACK_BOARD=board, MAVSTACK_NATIVE="1" if native else "0")
    # Room for a traceback when the heap is locked: a MemoryError then says where.
    cflags = "-DMICROPY_EMERGENCY_EXCEPTION_BUF_SIZE=256"
    if filesystem:
        cflags += " -DMAVSTACK_BOOT=1"
    elif frozen and _restart_word(board):
        cflags += " -DMAVSTACK_RESTART_WORD=%#x" % _restart_word(board)
    cmd = ["make", "-C", os.path.join(src, "ports", "qemu"), "-j%d" % (os.cpu_count() or 2),
           "BOARD=" + port_board, "BUILD=" + bdir, "MICROPY_HEAP_SIZE=%d" % (heap_kb * 1024),
           "CFLAGS_EXTRA=" + cflags]
    if filesystem:
        cmd += ["MICROPY_VFS_LFS2=1", "LDSCRIPT=" + _linker_script(src, port_board, os.path.dirname(manifest))]
    if frozen:
        cmd.append("FROZEN_MANIFEST=" + (manifest or os.path.join(ROOT, "firmware", "manifest.py")))
    else:
        cmd.append("FROZEN_MANIFEST=")
    r = subprocess.run(cmd, env=env, capture_output=quiet, text=True)
    if r.returncode:
        sys.stderr.write((r.stdout or "")[-4000:] + (r.stderr or "")[-4000:])
        raise RuntimeError("mcu: firmware build failed for %s" % board)
    _check_storage_region(board, os.path.join(bdir, "firmware.elf"), filesystem)
    shutil.copyfile(os.path.join(bdir, "firmware.elf"), out)
    return out


def build_dir(board, frozen=True, manifest=None, filesystem=False):
    """The build directory of a firmware: its objects, firmware.map, and for a frozen
    one frozen_content.c and .o, what bench/bench_mcu_flash.py measures."""
    tag = "%s-%s" % (board, "frozen" if frozen else "plain") if manifest is None else "%s-%s" % (
        board, os.path.basename(manifest)[:-3])
    return os.path.join(BUILD, "obj-" + (board + "-fs" if filesystem else tag))


def _region(board, name):
    """(start, size) of a RAM region a profile reserves: STORAGE_REGION, FS_REGION."""
    with open(os.path.join(ROOT, "boards", board + ".py")) as f:
        m = re.search(r"^%s = \((0x[0-9A-Fa-f]+), (0x[0-9A-Fa-f]+)\)" % name, f.read(), re.M)
    if m is None:
        raise RuntimeError("mcu: boards/%s.py has no %s" % (board, name))
    return int(m.group(1), 16), int(m.group(2), 16)


def _restart_word(board):
    """The profile's RESTART_WORD (mavstack/qemu.py's watchdog), or None."""
    with open(os.path.join(ROOT, "boards", board + ".py")) as f:
        m = re.search(r"^RESTART_WORD = (0x[0-9A-Fa-f]+)", f.read(), re.M)
    return int(m.group(1), 16) if m else None


def _check_storage_region(board, elf, filesystem=False):
    """The profile's RAM storage region (and the filesystem's) must lie above everything
    the firmware uses (its .bss holds the GC heap), below the stack's 16 KB, apart."""
    regions = [_region(board, "STORAGE_REGION")] + ([_region(board, "FS_REGION")] if filesystem else [])
    syms = {}
    for line in _sh(["arm-none-eabi-nm", elf], capture_output=True, text=True).stdout.splitlines():
        parts = line.split()
        if len(parts) == 3:
            syms[parts[2]] = int(parts[0], 16)
    for start, size in regions:
        if not syms["_ebss"] <= start or not start + size <= syms["_estack"] - 16 * 1024:
            raise RuntimeError("mcu: %s's region %#x+%#x overlaps the firmware's RAM (ends %#x) "
                               "or the stack (below %#x)" % (board, start, size, syms["_ebss"], syms["_estack"]))
    if len(regions) == 2 and not (regions[0][0] + regions[0][1] <= regions[1][0]
                                  or regions[1][0] + regions[1][1] <= regions[0][0]):
        raise RuntimeError("mcu: %s's STORAGE_REGION and FS_REGION overlap" % board)


# Run at every reset of the firmware with a filesystem (-DMAVSTACK_BOOT): the frozen
# _boot.py mounts it, then main.py from it runs if the reset was to the friendly REPL
# (as on MicroPython's other ports: a soft reset from the raw REPL, mpremote's, runs none).
_BOOT_MARK = "/* mavstack: boot from the filesystem */"
_BOOT_C = _BOOT_MARK + """
        #ifdef MAVSTACK_BOOT
        pyexec_frozen_module("_boot.py", false);
        if (pyexec_mode_kind == PYEXEC_MODE_FRIENDLY_REPL) {
            pyexec_file_if_exists("main.py");
        }
        #endif
"""
# Run at every reset of the frozen firmware of a profile with a RESTART_WORD: main.py
# again when the word says a watchdog ran when the board reset (mavstack/qemu.py).
_RESTART_MARK = "/* mavstack: start main.py again after a watchdog's reset */"
_RESTART_C = _RESTART_MARK + """
        #ifdef MAVSTACK_RESTART_WORD
        if (*(volatile uint32_t *)MAVSTACK_RESTART_WORD) {
            pyexec_file_if_exists("main.py");
        }
        #endif
"""
_TIME_C = _BOOT_MARK + """
#ifdef MAVSTACK_BOOT
// littlefs stamps files with the time; the port has no clock (no time module).
uint64_t mp_hal_time_ns(void) {
    return 0;
}
#endif
"""


def _patch_boot(src):
    """Give the qemu port's main.c the boot sequences above (once; inert without
    -DMAVSTACK_BOOT or -DMAVSTACK_RESTART_WORD, so the other builds are unchanged)."""
    path = os.path.join(src, "ports", "qemu", "main.c")
    with open(path) as f:
        text = f.read()
    if _RESTART_MARK in text:
        return
    anchor = "        mp_init();\n"
    if anchor not in text or "void gc_collect(void) {" not in text:
        raise RuntimeError("mcu: %s is not the main.c the boot patch expects" % path)
    if _BOOT_MARK not in text:
        text = text.replace(anchor, anchor + _BOOT_C, 1)
        text = text.replace("void gc_collect(void) {", _TIME_C + "\nvoid gc_collect(void) {", 1)
    text = text.replace(anchor, anchor + _RESTART_C, 1)
    with open(path, "w") as f:
        f.write(text)


def _boot_manifest(board):
    """A manifest freezing mcu/boot_fs.py as _boot.py, with the profile's FS_REGION."""
    d = os.path.join(BUILD, "boot-" + board)
    os.makedirs(d, exist_ok=True)
    start, size = _region(board, "FS_REGION")
    with open(os.path.join(ROOT, "mcu", "boot_fs.py")) as f:
        text = f.read()
    text = re.sub(r"^REGION = .*$", "REGION = (%#x, %#x)" % (start, size), text, count=1, flags=re.M)
    with open(os.path.join(d, "_boot.py"), "w") as f:
        f.write(text)
    manifest = os.path.join(d, "manifest.py")
    with open(manifest, "w") as f:
        f.write("freeze(%r, '_boot.py')\n" % d)
    return manifest


def _linker_script(src, port_board, workdir):
    """The board's linker script without unwind tables: littlefs' 64-bit arithmetic
    brings libgcc's .ARM.exidx, which the port's script does not place (nothing unwinds)."""
    with open(os.path.join(src, "ports", "qemu", "boards", port_board, "mpconfigboard.mk")) as f:
        name = re.search(r"^LDSCRIPT = (\S+)", f.read(), re.M).group(1)
    with open(os.path.join(src, "ports", "qemu", name)) as f:
        text = f.read()
    end = text.rindex("}")
    out = os.path.join(workdir, os.path.basename(name))
    with open(out, "w") as f:
        f.write(text[:end] + "\n    /DISCARD/ : { *(.ARM.exidx*) *(.ARM.extab*) }\n" + text[end:])
    return out


def _boot_inputs(board):
    return [os.path.abspath(__file__), os.path.join(ROOT, "mcu", "boot_fs.py"),
            os.path.join(ROOT, "boards", board + ".py")]


def _manifest_inputs(manifest):
    """Files whose change means a rebuild: the stack, the boards, the manifests."""
    paths = [os.path.join(ROOT, "firmware", "manifest.py"), os.path.abspath(__file__),
             os.path.join(ROOT, "host_tools", "stack_files.py")]  # the manifest's list of modules
    if manifest:
        paths.append(manifest)
    for top in ("firmware", "boards") + ((os.path.dirname(manifest),) if manifest else ()):
        for d, _subdirs, files in os.walk(os.path.join(ROOT, top)):
            paths += [os.path.join(d, n) for n in files if n.endswith(".py")]
    return paths


def flash_kb(elf):
    """Size of the firmware image (text + data) in KB."""
    r = _sh(["arm-none-eabi-size", elf], capture_output=True, text=True)
    text, data = r.stdout.splitlines()[1].split()[:2]
    return (int(text) + int(data)) / 1024


def qemu_command(board, elf, serials):
    """qemu-system-arm for a board with the given -serial backends (first: UART0)."""
    _port_board, machine, _native = BOARDS[board]
    cmd = ["qemu-system-arm"] + machine + ["-nographic", "-monitor", "none", "-semihosting",
                                           "-kernel", elf]
    for s in serials:
        cmd += ["-serial", s]
    return cmd


def main(argv):
    if not argv or argv[0] not in ("build", "repl", "run"):
        raise SystemExit(__doc__)
    heap = DEFAULT_HEAP_KB
    if "--heap-kb" in argv:
        heap = int(argv[argv.index("--heap-kb") + 1])
    boards = [a for a in argv[1:] if a in BOARDS] or list(BOARDS)
    if argv[0] == "build":
        for b in boards:
            t = time.time()
            elf = build(b, heap)
            print("%s: %s (%.0f KB, %.0f s)" % (b, elf, flash_kb(elf), time.time() - t))
    elif argv[0] == "run":
        elf = build_with_filesystem(boards[0])
        print("%s: the REPL is the first pty QEMU names, MAVLink the second; Ctrl-C stops" % boards[0])
        os.execvp("qemu-system-arm", qemu_command(boards[0], elf, ["pty", "pty"]))
    else:
        elf = build(boards[0], heap)
        os.execvp("qemu-system-arm", qemu_command(boards[0], elf, ["mon:stdio"]))


if __name__ == "__main__":
    main(sys.argv[1:])
