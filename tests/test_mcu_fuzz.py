"""The 32-bit boards fuzzed: the emulated Cortex-M3 and Cortex-M0 (boards/qemu_m3.py,
qemu_m0.py: status, params, commands, missions, streams and signing, frozen, viper kernels
on the M3 and portable ones on the M0; heap locked once up) get MCU_FUZZ_SECONDS (default
60; half of it on the slower M0) of the fuzzer's structured frames over their MAVLink UART,
in batches each closed by a sentinel command whose COMMAND_ACK says the board has handled
it. Then the board answers a parameter read, and its held heap at shutdown (board.HEAP:
collected, then gc.mem_alloc, as bench/bench_mcu.py reads it) is what it is after a run
without fuzz. Left out of the frames: SETUP_SIGNING (a key the test would not know would
lock it out) and PREFLIGHT_REBOOT_SHUTDOWN (the board would stop or restart). A fault the
console reports fails the test: those it found are fixed (docs/reliability.md). The M0's
one UART carries its console between the frames: read from the same stream.
"""
import os
import random
import re
import sys
import tempfile
import time

import pytest

from conftest import ROOT, recv
from gcs_tools import command
from mcu_rig import EmulatedBoard
from test_mcu import _gate

sys.path.insert(0, os.path.join(ROOT, "tests"))
from fuzz import frames, wire  # noqa: E402
from fuzz.rig import FuzzVehicle  # noqa: E402

FUZZ_SECONDS = float(os.environ.get("MCU_FUZZ_SECONDS", "60"))
_GC_NOISE = 256  # bytes
BATCH = 24  # frames between sentinels
_SETUP_SIGNING = 256
_REBOOT_SHUTDOWN = 246
_FORCE_REBOOT = 20190226.0  # PREFLIGHT_REBOOT_SHUTDOWN param6: even when armed


def _generator():
    """Structured frames of what the board's services handle (the same services in process)."""
    with tempfile.TemporaryDirectory() as d:
        v = FuzzVehicle(os.path.join(d, "st"))
        ids = [i for i, h in v.ep._handlers.items() if h and i != _SETUP_SIGNING]
        commands = [c for c in v.ep.commands if c != _REBOOT_SHUTDOWN]
        names = [v.params.name(i) for i in range(v.params.count)]
        v.ep.close()
    return frames.Structured(ids, commands, names)


def _acked(gcs, cmd, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        m = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)
        if m is not None and m.command == cmd:
            return True
    return False


def _fuzz(gcs, seconds):
    """Fuzzed batches for `seconds` -> frames the board confirmed handling."""
    gen = _generator()
    rng = random.Random(7)
    sentinel = wire.Sentinel(frames.LAYOUTS, wire.Signing())
    handled = seq = 0
    end = time.time() + seconds
    while time.time() < end:
        batch = []
        for _ in range(BATCH):
            seq += 1
            key = rng.randbytes(32) if rng.random() < 0.1 else None  # signed, with no key in force
            batch.append(gen.frame(rng, seq, key=key, stamp=rng.randrange(1 << 48)))
        cmd, f = sentinel.next()
        gcs.write(b"".join(batch) + wire.PAD + f)
        for _ in range(20):  # (an ACK the board's budget held back: ask again)
            if _acked(gcs, cmd, 1.0):
                handled += len(batch)
                break
            cmd, f = sentinel.next()
            gcs.write(wire.PAD + f)
        else:
            raise AssertionError("the board stopped answering after %d frames" % handled)
    return handled


def _shut_down(gcs, b):
    """Shut the vehicle down (main.py returns to the REPL), whatever the fuzz left: armed
    (forced, param6), or another station in control (released once its heartbeats stop,
    GCS_TIMEOUT_MS): asked again until ACCEPTED. The REPL must not be read before."""
    result = None
    for _ in range(12):
        command(gcs, _REBOOT_SHUTDOWN, 2.0, 0, 0, 0, 0, _FORCE_REBOOT, target=(1, 1))
        got = recv(gcs, "COMMAND_ACK", 2.0, lambda m: m.command == _REBOOT_SHUTDOWN)
        result = None if got is None else got.result
        if result == 0:
            return
        time.sleep(1.0)
    raise AssertionError("shutdown not accepted (last result %s)\n%s" % (result, _readable(b.console())))


class _Raw:
    """What a one-UART board sent, frames and console lines together (pymavlink's
    logfile_raw): its console is read from it."""

    def __init__(self):
        self.data = bytearray()

    def write(self, b):
        self.data += b

    def text(self):
        return self.data.decode("latin-1")


def _readable(console):
    """A console's printable runs of 4 or more characters (on a one-UART board, its text
    from among the frames' bytes)."""
    return "\n".join(re.findall(r"[ -~]{4,}", console))


def _session(board, fuzz_seconds):
    """Boot the vehicle, fuzz it (or not), read a parameter, shut it down -> (held heap in
    bytes, frames handled, the console)."""
    with EmulatedBoard(board) as b:
        gcs = b.start_vehicle()
        raw = None
        if b.uarts == 1:
            raw = gcs.logfile_raw = _Raw()
            b.console = lambda wait=0: raw.text()
        gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
        handled = _fuzz(gcs, fuzz_seconds) if fuzz_seconds else 0
        got = None
        for _ in range(5):
            gcs.mav.param_request_read_send(1, 1, b"SIM_SPEED", -1)
            got = recv(gcs, "PARAM_VALUE", 2.0, lambda m: m.param_id == "SIM_SPEED")
            if got is not None:
                break
        assert got is not None, "no answer to PARAM_REQUEST_READ after the fuzz\n" + _readable(b.console())
        console = b.console()
        _shut_down(gcs, b)
        time.sleep(1.0)
        if raw is not None:
            gcs.close()
            b.reopen_repl()
        out = b.exec("import board\nprint(board.HEAP[0])")
    return int(out.split()[-1]), handled, console


@pytest.mark.parametrize("board", ["qemu_m3", "qemu_m0"])
def test_board_fuzzed_over_its_uart(board):
    _gate()
    seconds = FUZZ_SECONDS if board == "qemu_m3" else FUZZ_SECONDS / 2
    held, _, _ = _session(board, 0)
    held_fuzzed, handled, console = _session(board, seconds)
    print("frames handled:", handled, "held heap:", held, "after the fuzz:", held_fuzzed)
    assert handled >= 10 * seconds, handled
    assert "Traceback" not in console, _readable(console)
    faults = [line for line in console.splitlines() if "Fault:" in line or "MemoryError" in line]
    assert not faults, _readable(console)
    # Collected at shutdown, the fuzzed vehicle holds what the other does, within the
    # conservative collector's noise (a stale word on the stack keeps a few blocks).
    assert held_fuzzed <= held + _GC_NOISE, (held, held_fuzzed)
