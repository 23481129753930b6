"""Put mavstack on a board: compile it to .mpy for the board's CPU (flash_tree.py), copy
it over the board's REPL port with mpremote (flash_device.py), soft-reset it and wait
for the vehicle's HEARTBEAT; or, with --build-only, write the tree into a directory.
`mavctl flash ...` and `python -m mavctl.flash_build ...` are this command.

    mavctl flash --board pico [--port /dev/ttyACM0]
    mavctl flash --board esp32 --build-only build/esp32

With a board attached, its firmware's .mpy version, CPU and machine are read first and
a profile made for another board is refused before anything is copied. Options, exit
statuses and .mpy compatibility: docs/mavctl.md.
"""
import argparse
import os
import shutil
import sys

from mavctl import ROOT
from mavctl.errors import EXIT_MPY_VERSION
from mavctl.flash_device import Board, DeviceError, default_port, prepare_script, wait_heartbeat
from mavctl.flash_tree import (ARCH, ARCH_BY_INDEX, MPY_SUB_VERSION, MPY_VERSION, FlashError, build,
                               prepare_out, read_profile)
from mavctl.progress import progress

THUMB = ("armv6m", "armv7m", "armv7em", "armv7emsp", "armv7emdp")  # each loads the ones before it


def loads_on(arch, dev_arch):
    """True if firmware reporting dev_arch loads native code built for arch."""
    if arch in THUMB and dev_arch in THUMB:
        return THUMB.index(arch) <= THUMB.index(dev_arch)
    return arch == dev_arch


def check_board(board, settings, arch, dev_arch, machine):
    """Refuse a profile made for another board before anything is copied: its CPU must
    be one the firmware runs (the arch it reports), and its MACHINE, if it names one,
    part of the firmware's machine string."""
    want = settings.get("MACHINE")
    if want and machine and want not in machine:
        raise FlashError("board profile %s is for a %s; the board is a %s: wrong --board? "
                         "nothing was copied" % (board, want, machine))
    if arch and dev_arch and arch != "host" and not loads_on(arch, dev_arch):
        raise FlashError("board profile %s is for CPU %s; the board's firmware is %s: wrong --board? "
                         "nothing was copied" % (board, arch, dev_arch))


def _prepare_script(files):
    """What flash runs on the board before copying (flash_device.prepare_script)."""
    return prepare_script(files)


def flash_device(args, messages):
    """Read the board, build for it, copy the tree, reset, wait for the vehicle."""
    _, settings, _ = read_profile(args.board)
    port = args.port or default_port()
    board = Board(port)
    try:
        board.open()
        version, sub, index, fw, machine = board.info()
        if version != MPY_VERSION:
            raise FlashError(
                "the board runs MicroPython %s (.mpy v%d); this build makes .mpy v%d.%d: update its "
                "firmware to MicroPython 1.23 or later" % (fw, version, MPY_VERSION, MPY_SUB_VERSION),
                EXIT_MPY_VERSION)
        dev_arch = ARCH_BY_INDEX[index] if 0 < index < len(ARCH_BY_INDEX) else None
        arch = args.arch or settings.get("MPY_ARCH") or ARCH.get(args.board) or dev_arch
        if not args.arch:
            check_board(args.board, settings, arch, dev_arch, machine)
        native = sub == MPY_SUB_VERSION and dev_arch is not None
        if not native:
            print("flash: firmware %s cannot load native .mpy v%d.%d: leaving viper code out "
                  "(portable kernels)" % (fw, MPY_VERSION, MPY_SUB_VERSION))
        print("flash: %s, MicroPython %s, %s: building for %s" % (port, fw, machine, arch))
        out = os.path.join(ROOT, "build", args.board)
        files = build_tree(args, out, arch, messages, native)
        with progress("flash") as bar:
            copied, unchanged, removed = board.sync(out, files, bar)
        print("flash: %d files copied, %d unchanged, %d stale removed" % (copied, unchanged, removed))
        board.reset()
        mav = args.mavlink or port
        if mav == port:  # one UART: MAVLink has it once the vehicle runs
            board.close()
            board = None
        msg, said = wait_heartbeat(mav, args.timeout, board)
        for line in said:
            if line.startswith("mavstack:"):  # what main.py says of the vehicle it built
                print("flash: the board says: " + line[9:].strip())
        print("flash: the vehicle is up: HEARTBEAT from system %d on %s" % (msg.get_srcSystem(), mav))
        return 0
    finally:
        if board is not None:
            board.close()


def build_tree(args, out, arch, messages, native):
    prepare_out(out)
    try:
        files = build(args.board, out, arch, args.with_meta, messages, args.opt, native)
    except FlashError:
        shutil.rmtree(out, ignore_errors=True)  # no half-built tree left behind
        raise
    size = sum(os.path.getsize(os.path.join(out, f)) for f in files)
    print("flash: %d files, %d bytes for %s in %s" % (len(files), size, args.board, out))
    return files


def main(argv=None):
    prog = os.path.basename(sys.argv[0] or "flash_build.py")
    ap = argparse.ArgumentParser(
        prog="mavctl flash" if prog == "mavctl" else prog,
        description="Compile mavstack for a board, copy it there with mpremote, reset the board "
                    "and wait for the vehicle's HEARTBEAT.")
    ap.add_argument("--board", required=True,
                    help="profile in boards/ (pico, esp32, pyboard, unix, qemu_m3)")
    ap.add_argument("--port", help="the board's REPL serial port (default: the one USB serial port)")
    ap.add_argument("--build-only", metavar="DIR",
                    help="write the tree the board would get into DIR; no device needed")
    ap.add_argument("--arch", help="mpy-cross -march (default: from the board, or the attached device)")
    ap.add_argument("--with-meta", action="store_true",
                    help="also ship the dialect's *_meta name tables and layout (costs RAM on import)")
    ap.add_argument("--messages", metavar="NAMES",
                    help="cut the dialect down to the messages the stack names plus these "
                         "(comma separated names or ids; '' for none extra)")
    ap.add_argument("--opt", type=int, default=0, choices=range(4), help="mpy-cross -O level")
    ap.add_argument("--mavlink", metavar="PORT",
                    help="the board's MAVLink serial port, where flash waits for the vehicle's "
                         "HEARTBEAT after the reset (default: --port, a board with one UART)")
    ap.add_argument("--timeout", type=float, default=60.0,
                    help="seconds to wait for that HEARTBEAT (default 60)")
    args = ap.parse_args(argv)
    messages = None if args.messages is None else args.messages.split(",")
    try:
        if not args.build_only:
            return flash_device(args, messages)
        build_tree(args, args.build_only, args.arch, messages, True)
        return 0
    except (FlashError, DeviceError) as e:
        print("flash: %s" % e, file=sys.stderr)
        return e.status
    except KeyboardInterrupt:
        return 2


if __name__ == "__main__":
    sys.exit(main())
