"""The MCU stage: mavstack on emulated Cortex-M3 (viper) and Cortex-M0 (portable) boards,
MicroPython's qemu port with the stack frozen in (mcu/firmware.py, tests/mcu_rig.py).

Each steady-state script of tests/mpy runs on both CPUs with the heap locked and
micropython.mem_total() checked; the whole vehicle boots on each board and a pymavlink
ground station on its MAVLink UART drives it (test_mcu_vehicle.py).

Without the tools (qemu-system-arm, gcc-arm-none-eabi) these tests are skipped with
the reason, except under CI=true, where that is a failure: `make mcu-deps` installs them.
"""
import os
import random
import re
import struct
import threading
import time

import pytest

from mcu_rig import TEST_MANIFEST, TESTS_MPY, EmulatedBoard, skip_reason
from wire_oracle import corrupt, decode_frames, full_len

BOARDS = ("qemu_m3", "qemu_m0")
SCRIPT_HEAP_KB = 160  # the steady-state scripts build their own benches: room for those


def _gate():
    why = skip_reason()
    if why and os.environ.get("CI") == "true":
        pytest.fail(why + " -- CI must run the MCU stage")
    if why:
        pytest.skip(why)


@pytest.fixture(params=BOARDS)
def board(request):
    _gate()
    with EmulatedBoard(request.param, SCRIPT_HEAP_KB, TEST_MANIFEST) as b:
        yield b


def _kernels(b):
    return "viper" if b.board == "qemu_m3" else "portable"


# --- the wire layer, through the MAVLink UART ------------------------------------------


def _crc16(data, crc):
    for byte in data:
        t = (byte ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc


def _digest(frames):
    crc = 0xFFFF
    for f in frames:
        hdr = 10 if f[0] == 0xFD else 6
        msgid = f[5] if hdr == 6 else f[7] | f[8] << 8 | f[9] << 16
        p = bytes(f[hdr:hdr + f[1]])
        p += bytes(full_len("common", msgid) - len(p))
        crc = _crc16(p, crc ^ (msgid & 0xFF))
    return crc


def test_wire_parse_and_encode_locked_over_the_uart(board):
    from test_wire_heaplock import mixed_frames

    rnd = random.Random(8)
    frames = mixed_frames(rnd, 1500)
    stream, intact = corrupt(rnd, frames, rate=0.05, garbage_rate=0.1)
    stream = bytes(stream) + bytes(300)  # the parser finishes the last candidate
    intact = [frames[i] for i in intact]
    count = 600
    with open(os.path.join(TESTS_MPY, "wire_uart.py")) as f:
        src = f.read()
    out = board.start_script(src, [len(stream), count])
    uart = board.mavlink_serial()
    got = bytearray()
    stop = threading.Event()

    def reader():
        while not stop.is_set():
            try:
                data = uart.read(uart.in_waiting or 1)
            except Exception:  # finish_script closed the port under the read: all is in
                return
            got.extend(data)

    t = threading.Thread(target=reader, daemon=True)
    t.start()
    uart.write(stream)
    uart.write(stream)
    text = board.finish_script(out, got, timeout=300, expect=b"encode %d" % count, times=2)
    stop.set()
    t.join(2)
    assert "kernels " + _kernels(board) in text, text
    rounds = re.findall(r"round (\w+) bytes (\d+) requested (\d+)", text)
    assert [r[0] for r in rounds] == ["unlocked", "locked"], text
    assert all(int(r[1]) == len(stream) for r in rounds), text
    # The locked round passed, and the unlocked one asked the heap for nothing either
    # (mem_total: it sees the frame states the VM would take from the heap for
    # functions with many locals, which under heap_lock fall back to the C stack).
    assert rounds[0][2] == "0", text
    want = "parse %d digest %d signed %d" % (len(intact), _digest(intact),
                                             sum(1 for f in intact if f[0] == 0xFD and f[2] & 1))
    parses = re.findall(r"parse \d+ digest \d+ signed \d+", text)
    assert parses == [want, want], text
    msgs = decode_frames("common", 2, bytes(got))
    msgs = [m for m in msgs if m.get_type() != "BAD_DATA"]
    assert len(msgs) == 2 * count
    assert [m.get_msgbuf()[0] for m in msgs[:4]] == [0xFE, 0xFD, 0xFE, 0xFD]
    hbs = [m.custom_mode for m in msgs if m.get_type() == "HEARTBEAT"]
    assert hbs == list(range(0, count, 6)) * 2
    gps = [m for m in msgs if m.get_type() == "GPS_RAW_INT"]
    assert [m.lat for m in gps[:3]] == [-2, -8, -14] and gps[0].time_usec == 2000


# --- the steady-state scripts the unix port runs, on both CPUs ---------------------------

# script, arguments: each prints a last line starting with "ok" when its checks and its
# run under heap_lock() pass, and "requested=N": what the whole steady state asked of the
# heap unlocked (mem_total: it sees the frame states the VM takes from the heap for
# functions with many locals, which under heap_lock fall back to the C stack). Both are
# held to 0, as are the services' own paths ("own=0").
STEADY = (
    ("params_steady.py", ["bytewise", 2, 5760]),
    ("params_steady.py", ["c_cast", 1, 5760]),
    ("missions_steady.py", ["ram", 100, "own"]),
    ("missions_runner_steady.py", ["ram", "own"]),
    ("signing_steady.py", [300, "lock"]),
    ("streams_steady.py", [2, 5760, 10000, 3]),  # 10,000 scheduler ticks, ten streams
    ("status_steady.py", ["status,commands", "-", 3000]),
    ("inputs_steady.py", [1500]),  # every pilot input, loss, echoes, HIL_CONTROLS
    ("seed_steady.py", ["common", 3]),  # geography, debug, servos, auth, calibration, seed commands
    ("faults_steady.py", [100]),  # a raising handler and tick: contained, params/missions/streams go on
    ("route_steady.py", [3000]),  # frames forwarded between three links (router.py)
    ("peripheral_steady.py", [2000]),  # a peripheral: sysid followed, its output, camera, commands
    ("fuzz_found.py", ["-"]),  # what tests/test_mcu_fuzz.py found: ints past 2^30, huge floats
)


@pytest.mark.parametrize("script,args", STEADY, ids=["%s-%s" % (s[:-3], a[0]) for s, a in STEADY])
def test_steady_state_scripts_heap_locked(board, script, args):
    out = board.run_script(os.path.join(TESTS_MPY, script), args, timeout=900)
    lines = out.strip().splitlines()
    assert lines and lines[-1].lower().startswith("ok"), out
    assert "own=" not in lines[-1] or "own=0 " in lines[-1], out
    assert " requested=0 " in lines[-1] + " ", out
    print("%s %s: %s" % (board.board, script, lines[-1]))
