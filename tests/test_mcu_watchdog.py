"""The watchdog and the crash-loop guard on the emulated Cortex-M3 (boards/qemu_m3.py):
QEMU's MPS2-AN385 maps a CMSDK APB watchdog, which mavstack/qemu.py drives; the
micro:bit (qemu_m0) maps none (docs/reliability.md). The unix port's: test_watchdog.py.

Both tests run a firmware of their own (tests/watchdog/), the M3's with faults on demand,
in the vehicle's smallest heap (mcu/firmware.py's default). A handler that never returns
(MAV_CMD_USER_1's): the board resets, the firmware starts the vehicle again (the restart word,
mcu/firmware.py) and it is back with its parameters and mission from the RAM storage,
which a reset keeps; HEARTBEAT within the timeout plus the boot. The application failing
at every start (its APP_FAULT parameter): after 3 resets the board starts in safe mode
and says so; a ground station puts the parameter right, and after the clean run the
next start is a normal one.
"""
import os
import struct
import threading
import time

import pytest

from conftest import ROOT, recv
from gcs_tools import run
from mcu_rig import EmulatedBoard
from mission_gcs import MissionClient, plan, same
from test_mcu import _gate

SAFE_TEXT = "Safe mode after 3 resets: status,params,commands"
FAULTS_MANIFEST = os.path.join(ROOT, "tests", "watchdog", "faults_manifest.py")
PREFLIGHT_STORAGE = 245
PREFLIGHT_REBOOT_SHUTDOWN = 246
INT32, REAL32 = 6, 9

class Console(threading.Thread):
    """The REPL UART read as it comes: when the board printed what."""

    def __init__(self, serial):
        super().__init__(daemon=True)
        self.serial = serial
        self.lines = []  # (time, line)
        self.stopped = False

    def run(self):
        buf = b""
        while not self.stopped:
            try:
                data = self.serial.read(max(1, self.serial.in_waiting))
            except Exception:
                return
            buf += data
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                self.lines.append((time.time(), line.decode(errors="replace").strip()))

    def first(self, text, after=0.0, wait=3.0):
        """When a line with text was printed after `after` (waiting for it), or None."""
        deadline = time.time() + wait
        while True:
            for t, line in list(self.lines):
                if t > after and text in line:
                    return t
            if time.time() > deadline:
                return None
            time.sleep(0.05)

    def count(self, text):
        return sum(text in line for _, line in self.lines)


def _param(m, name, value=None, ptype=REAL32):
    for _ in range(3):
        if value is None:
            m.mav.param_request_read_send(1, 1, name.encode(), -1)
        else:
            m.mav.param_set_send(1, 1, name.encode(), value, ptype)
        p = recv(m, "PARAM_VALUE", 2.0, lambda p: p.param_id == name)
        if p is not None:
            return p
    return None


def _bits(v):
    return struct.unpack("<f", struct.pack("<i", v))[0]


def _ints(f):
    return struct.unpack("<i", struct.pack("<f", f))[0]


def _safe_texts(m, seconds, until=None):
    n = 0
    deadline = time.time() + seconds
    while time.time() < deadline and n != until:
        t = recv(m, "STATUSTEXT", 0.3)
        if t is not None and t.text == SAFE_TEXT:
            assert t.severity == 2
            n += 1
    return n


@pytest.fixture
def faulty_m3():
    _gate()
    with EmulatedBoard("qemu_m3", manifest=FAULTS_MANIFEST) as b:
        yield b


def test_a_hung_loop_resets_the_board_and_the_vehicle_comes_back(faulty_m3):
    m = faulty_m3.start_vehicle()
    console = Console(faulty_m3.repl.serial)
    console.start()
    assert _param(m, "SIM_SPEED", 8.5).param_value == 8.5
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    items = plan(20, tag=3)
    assert MissionClient(m).upload(items) == 0

    # (MAV_CMD_USER_1) its handler never returns: nothing feeds the watchdog
    m.mav.command_long_send(1, 1, 31010, 0, 0, 0, 0, 0, 0, 0, 0)
    hung = time.time()
    back = None
    while back is None and time.time() < hung + 10.0:
        hb = recv(m, "HEARTBEAT", 10.0)
        # MAV_STATE_BOOT: a vehicle starting (any later one: none comes while it hangs)
        if hb is not None and (hb.system_status == 1 or time.time() > hung + 1.5):
            back = time.time()
    assert back is not None, console.lines
    ready = console.first("mavstack: qemu_m3 ready", after=hung)  # printed once it is built
    assert ready is not None, console.lines
    # The reset comes WATCHDOG_MS after the last feed; then MicroPython boots and runs
    # main.py (the restart word), whose status service sends HEARTBEAT as it attaches.
    print("qemu_m3: HEARTBEAT %.2f s after the loop hung (timeout 2.0 s: %.2f s after the reset)"
          % (back - hung, back - hung - 2.0))
    assert 2.0 - 0.2 < back - hung < 2.0 + 3.0
    assert ready - hung < 2.0 + 3.0

    assert _param(m, "SIM_SPEED").param_value == 8.5
    got = MissionClient(m).download()
    assert got is not None and same(got, items)
    assert recv(m, "ATTITUDE", 3.0) is not None  # the application too
    console.stopped = True


def test_three_resets_start_safe_mode_until_a_clean_run(faulty_m3):
    m = faulty_m3.start_vehicle()
    console = Console(faulty_m3.repl.serial)
    console.start()
    assert _param(m, "SIM_SPEED", 6.5).param_value == 6.5
    assert _ints(_param(m, "APP_FAULT", _bits(1), INT32).param_value) == 1
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    items = plan(10, tag=5)
    assert MissionClient(m).upload(items) == 0
    assert run(m, PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0  # acknowledged: it does not count
    t0 = time.time()

    # The start fails (in place), and twice more after the watchdog's resets; the
    # third reset starts safe mode, said every second.
    assert _safe_texts(m, 40.0, until=1) == 1, console.lines
    print("qemu_m3: safe mode %.1f s after the reboot" % (time.time() - t0))
    assert console.count("RuntimeError: APP_FAULT 1: the application fails at start-up") == 3, \
        "\n".join(line for _, line in console.lines)
    assert console.count("mavstack: " + SAFE_TEXT) == 1
    assert _safe_texts(m, 2.2) >= 2
    assert recv(m, "ATTITUDE", 1.0) is None  # no application, no streams
    assert MissionClient(m, timeout=0.3, retries=1).download() is None  # no missions

    # Put right from the ground station; the clean run (5 s on this board) ends the texts.
    assert _ints(_param(m, "APP_FAULT", _bits(0), INT32).param_value) == 0
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    time.sleep(3.0)
    assert _safe_texts(m, 1.5) == 0
    assert run(m, PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0

    # A normal start: the application, every service, what was stored.
    assert recv(m, "ATTITUDE", 10.0) is not None
    assert _safe_texts(m, 1.5) == 0
    assert _param(m, "SIM_SPEED").param_value == 6.5
    got = MissionClient(m).download()
    assert got is not None and same(got, items)
    lines = [line for _, line in console.lines]
    bad = [i for i, line in enumerate(lines) if "MemoryError" in line or "Fault" in line]
    assert not bad, "\n".join(lines[max(0, bad[0] - 12):bad[0] + 2])
    console.stopped = True
