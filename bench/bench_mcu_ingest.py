"""Ingest on the emulated Cortex-M3 against MAVLink's C library on the same core.

Both parse wire_streams.py's 20,000-frame streams on qemu_m3 (MPS2-AN385) under
qemu-system-arm -icount shift=0, where a guest instruction is one virtual ns, so CMSDK
APB timer 0 (25 MHz) ticks once every 40 instructions; each reads it around its parse
only. QEMU's loader puts the stream in RAM at STREAM, clear of both programs.
  C: bench/c_ingest_m3.c, mavlink_parse_char from pymavlink's mavgen C headers (common),
     arm-none-eabi-gcc -O2 -mcpu=cortex-m3 -mthumb, bare metal, its result by
     semihosting; its loop of known length checks the 40.
  mavstack: bench/mpy_ingest_m3.py on the frozen firmware (tests/mcu_rig.py), the
     parser with the viper kernels, 4 KiB chunks, the heap locked.
Instructions per frame = (ticks - ticks of the timing around nothing) x 40 / frames,
best of 3 passes. Keys for the MAVLink 2 stream, the same + _v1 for MAVLink 1;
mcu_ingest_ratio_m3 = mavstack / C. Figures and method: docs/testing.md.
"""
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile

BENCH = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(BENCH)
for _d in (BENCH, os.path.join(ROOT, "mcu"), os.path.join(ROOT, "tests")):
    if _d not in sys.path:
        sys.path.insert(0, _d)

import bench_wire_c  # noqa: E402
import firmware  # noqa: E402
import wire_streams  # noqa: E402

C_SOURCE = os.path.join(BENCH, "c_ingest_m3.c")
C_LDSCRIPT = os.path.join(BENCH, "c_ingest_m3.ld")
BOARD_SCRIPT = os.path.join(BENCH, "mpy_ingest_m3.py")
# Where QEMU's loader puts the stream: on the firmware, its storage and filesystem
# regions (boards/qemu_m3.py), which nothing uses while no vehicle runs.
STREAM = 0x00200000
LENGTH_WORD = 0x001FFFF0  # and its length, for the C program (c_ingest_m3.c)
STACK_ROOM = 16 * 1024  # below a firmware's _estack, kept clear of the stream
ICOUNT = ["-icount", "shift=0"]  # one guest instruction, one virtual ns
INSTR_PER_TICK = 40  # 10^9 virtual ns a second / the timer's 25 MHz
TARGET_RATIO = 4


def loader(path):
    return ["-device", "loader,file=%s,addr=%#x,force-raw=on" % (path, STREAM)]


def build_c(tmp):
    """Generate the C headers and build c_ingest_m3.c for the board -> its ELF."""
    from pymavlink.generator import mavgen

    include = os.path.join(tmp, "include")
    opts = mavgen.Opts(include, wire_protocol="2.0", language="C", validate=False)
    with contextlib.redirect_stdout(io.StringIO()):
        ok = mavgen.mavgen(opts, [bench_wire_c.common_xml()])
    if not ok or not os.path.isfile(os.path.join(include, "common", "mavlink.h")):
        raise RuntimeError("mavgen did not generate common/mavlink.h")
    elf = os.path.join(tmp, "c_ingest_m3.elf")
    p = subprocess.run(["arm-none-eabi-gcc", "-O2", "-mcpu=cortex-m3", "-mthumb", "-w", "-nostartfiles",
                        "-I", include, "-T", C_LDSCRIPT, "-o", elf, C_SOURCE],
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError("arm-none-eabi-gcc failed\n" + p.stdout + p.stderr)
    return elf


def check_room(elf, size):
    """The stream and the length word must lie where the program keeps nothing: above
    its .bss, and above its stack (C's) or below it with room to spare (the firmware's)."""
    out = subprocess.run(["arm-none-eabi-nm", elf], capture_output=True, text=True, check=True).stdout
    syms = {p[2]: int(p[0], 16) for p in (line.split() for line in out.splitlines()) if len(p) == 3}
    ebss, estack = syms["_ebss"], syms["_estack"]
    if ebss > LENGTH_WORD or not (estack <= LENGTH_WORD or STREAM + size <= estack - STACK_ROOM):
        raise RuntimeError("%s: the stream at %#x+%#x is not clear of its RAM (.bss ends %#x, stack %#x)"
                           % (os.path.basename(elf), STREAM, size, ebss, estack))


def c_ticks(elf, path):
    """-> (frames, ticks) of the C parser's best pass over the stream in this file."""
    size = os.path.getsize(path)
    check_room(elf, size)
    said = path + ".out"  # what it says by semihosting
    cmd = (firmware.qemu_command("qemu_m3", elf, []) + ICOUNT + loader(path)
           + ["-device", "loader,addr=%#x,data=%d,data-len=4" % (LENGTH_WORD, size),
              "-chardev", "file,id=said,path=" + said, "-semihosting-config", "enable=on,chardev=said"])
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if p.returncode != 0:
        raise RuntimeError("c_ingest_m3 failed (%d)\n%s%s" % (p.returncode, p.stdout, p.stderr))
    with open(said) as f:
        frames, best, empty, calibration, instructions = (int(x) for x in f.read().split())
    if abs(calibration * INSTR_PER_TICK - instructions) > instructions // 1000:
        raise RuntimeError("a loop of %d instructions took %d ticks: not %d instructions a tick"
                           % (instructions, calibration, INSTR_PER_TICK))
    return frames, best - empty


def mavstack_ticks(path):
    """-> (frames, ticks) of mavstack's best pass on the board over the stream in this file."""
    from mcu_rig import EmulatedBoard

    size = os.path.getsize(path)
    board = EmulatedBoard("qemu_m3", qemu_args=ICOUNT + loader(path))
    check_room(board.elf, size)
    with board as b:
        out = b.run_script(BOARD_SCRIPT, [STREAM, size])
    impl, frames, best, empty = out.split()[-4:]
    if impl != "viper":
        raise RuntimeError("the board parsed with the %s kernels, not viper" % impl)
    return int(frames), int(best) - int(empty)


def per_frame(frames, ticks):
    if frames != wire_streams.FRAMES:
        raise RuntimeError("%d frames parsed, not %d" % (frames, wire_streams.FRAMES))
    return round(ticks * INSTR_PER_TICK / frames)


def run():
    if firmware.tools_missing():
        raise RuntimeError("MCU tools missing (make mcu-deps): %s" % firmware.tools_missing())
    r = {}
    with tempfile.TemporaryDirectory() as tmp:
        _v1, _v2, v1_path, v2_path = wire_streams.write_streams(tmp)
        elf = build_c(tmp)
        for path, tag in ((v2_path, ""), (v1_path, "_v1")):
            c = per_frame(*c_ticks(elf, path))
            ours = per_frame(*mavstack_ticks(path))
            r["mcu_ingest_instr_per_frame_c_m3" + tag] = c
            r["mcu_ingest_instr_per_frame_mavstack_m3" + tag] = ours
            r["mcu_ingest_ratio_m3" + tag] = round(ours / c, 3)
    return r


def floors(r):
    text = "mcu_ingest_ratio_m3%s <= %d: mavstack within %dx of C's instructions per frame, MAVLink %d (%.2f)"
    return [(text % (tag, TARGET_RATIO, TARGET_RATIO, v, r["mcu_ingest_ratio_m3" + tag]),
             r["mcu_ingest_ratio_m3" + tag] <= TARGET_RATIO) for tag, v in (("", 2), ("_v1", 1))]


if __name__ == "__main__":
    results = run()
    print(json.dumps(results, indent=1))
    for text, ok in floors(results):
        print("%s: %s" % (text, "ok" if ok else "MISSED"))
