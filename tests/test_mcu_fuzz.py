"""The 32-bit board fuzzed: the emulated Cortex-M3 (boards/qemu_m3.py: status, params,
commands, missions, streams and signing, frozen; heap locked once up) gets MCU_FUZZ_SECONDS
(default 60) of the fuzzer's structured frames over its MAVLink UART, in batches each
closed by a sentinel command whose COMMAND_ACK says the board has handled it. Then it
answers a parameter read, and its held heap at shutdown (board.HEAP: collected, then
gc.mem_alloc, as bench/bench_mcu.py reads it) is what it is after a run without fuzz.
Left out of the frames: SETUP_SIGNING (a key the test would not know would lock it out)
and PREFLIGHT_REBOOT_SHUTDOWN (the board would stop or restart). A fault the console
reports fails the test: those it found are fixed (docs/reliability.md).
"""
import os
import random
import sys
import tempfile
import time

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
    raise AssertionError("shutdown not accepted (last result %s)\n%s" % (result, b.console()))


def _session(fuzz_seconds):
    """Boot the M3 vehicle, fuzz it (or not), read a parameter, shut it down -> (held heap
    in bytes, frames handled, the console)."""
    with EmulatedBoard("qemu_m3") as b:
        gcs = b.start_vehicle()
        gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
        handled = _fuzz(gcs, fuzz_seconds) if fuzz_seconds else 0
        got = None
        for _ in range(5):
            gcs.mav.param_request_read_send(1, 1, b"SIM_SPEED", -1)
            got = recv(gcs, "PARAM_VALUE", 2.0, lambda m: m.param_id == "SIM_SPEED")
            if got is not None:
                break
        assert got is not None, "no answer to PARAM_REQUEST_READ after the fuzz\n" + b.console()
        console = b.console()
        _shut_down(gcs, b)
        time.sleep(1.0)
        out = b.exec("import board\nprint(board.HEAP[0])")
    return int(out.split()[-1]), handled, console


def test_m3_board_fuzzed_over_its_uart():
    _gate()
    held, _, _ = _session(0)
    held_fuzzed, handled, console = _session(FUZZ_SECONDS)
    print("frames handled:", handled, "held heap:", held, "after the fuzz:", held_fuzzed)
    assert handled >= 10 * FUZZ_SECONDS, handled
    assert "Traceback" not in console, console
    faults = [line for line in console.splitlines() if "Fault:" in line or "MemoryError" in line]
    assert not faults, console
    # Collected at shutdown, the fuzzed vehicle holds what the other does, within the
    # conservative collector's noise (a stale word on the stack keeps a few blocks).
    assert held_fuzzed <= held + _GC_NOISE, (held, held_fuzzed)
