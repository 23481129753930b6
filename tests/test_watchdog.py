"""The watchdog and the crash-loop guard on the unix port (the emulated M3's:
tests/test_mcu_watchdog.py).

The unix vehicle's watchdog is a process, host_tools/watchdog.py, that runs it and starts
it again when its poll loop stops feeding it: a handler that never returns gets the
vehicle back with its parameters and mission, HEARTBEAT within the timeout plus its
start. A vehicle that fails at every start (tests/watchdog/faults.py: APP_FAULT raises or
hangs there) starts in safe mode after 3 such resets: status, params and commands, no
application, a STATUSTEXT a second saying so; the ground station puts the parameter
right, and after a clean run (CLEAN_RUN_MS, short here) the next start is a normal one.
The guard itself (mavstack/watchdog.py) on CPython: counting, sealing, clearing.
"""
import os
import signal
import struct
import subprocess
import time

import pytest

from conftest import FIRMWARE, PYTHON, ROOT, recv
from gcs_tools import listen, run
from mission_gcs import MissionClient, plan, same
from vehicle import Vehicle

WATCHDOG = os.path.join(ROOT, "host_tools", "watchdog.py")
FAULTS = os.path.join(ROOT, "tests", "watchdog")
SAFE_TEXT = "Safe mode after 3 resets: status,params,commands"
PREFLIGHT_STORAGE = 245
PREFLIGHT_REBOOT_SHUTDOWN = 246
INT32, REAL32 = 6, 9


class Watched(Vehicle):
    """The vehicle under its watchdog: host_tools/watchdog.py with main.py's arguments,
    the board (default faulty_unix, tests/watchdog/) importable."""

    def __init__(self, storage, board="faulty_unix", args=()):
        super().__init__(storage, board, args=args)

    def start(self):
        cmd = [PYTHON, WATCHDOG, "--board", self.board, "--storage", self.storage]
        for link in self.links:
            cmd += ["--link", link]
        env = dict(os.environ, MICROPYPATH=os.pathsep.join([FAULTS, FIRMWARE, os.path.join(ROOT, "boards"), ".frozen"]))
        self.proc = subprocess.Popen(cmd + self.args, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        return self


@pytest.fixture
def watched(tmp_path):
    started = []

    def start(*args):
        v = Watched(tmp_path / "storage", args=args).start()
        started.append(v)
        return v

    yield start
    for v in started:
        v.stop()


def heartbeat(m, timeout, after=0.0):
    """The vehicle's next HEARTBEAT arriving after `after`, ours sent meanwhile (a new
    vehicle's udpin link takes us as its peer from our first frame) -> when it came, or
    None."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        if recv(m, "HEARTBEAT", 0.2, lambda h: h.get_srcSystem() == 1) is not None and time.time() > after:
            return time.time()
    return None


def param(m, name, value=None, ptype=REAL32, timeout=5.0):
    """Set (value given) or read a parameter -> its PARAM_VALUE, None without one."""
    for _ in range(3):
        if value is None:
            m.mav.param_request_read_send(1, 1, name.encode(), -1)
        else:
            m.mav.param_set_send(1, 1, name.encode(), value, ptype)
        p = recv(m, "PARAM_VALUE", timeout / 3, lambda p: p.param_id == name)
        if p is not None:
            return p
    return None


def bits(v):
    """An integer as PARAM_SET carries it bytewise (and back: ints(value))."""
    return struct.unpack("<f", struct.pack("<i", v))[0]


def ints(f):
    return struct.unpack("<i", struct.pack("<f", f))[0]


def safe_texts(m, seconds, until=None):
    """The safe-mode STATUSTEXTs heard in `seconds` (or until that many), heartbeats
    sent meanwhile."""
    n = 0
    deadline = time.time() + seconds
    while time.time() < deadline and n != until:
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        t = recv(m, "STATUSTEXT", 0.3)
        if t is not None and t.text == SAFE_TEXT:
            assert t.severity == 2  # MAV_SEVERITY_CRITICAL
            n += 1
    return n


def test_a_hung_loop_restarts_the_vehicle_with_its_parameters_and_mission(watched):
    v = watched()
    m = v.gcs()
    assert param(m, "SIM_SPEED", 8.5).param_value == 8.5
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    items = plan(20, tag=7)
    assert MissionClient(m).upload(items) == 0

    # (MAV_CMD_USER_1) its handler never returns: nothing feeds the watchdog
    m.mav.command_long_send(1, 1, 31010, 0, 0, 0, 0, 0, 0, 0, 0)
    hung = time.time()
    back = heartbeat(m, 10.0, after=hung + 1.5)  # (none comes while it hangs)
    assert back is not None, v.output()
    assert back - hung < 2.0 + 3.0  # WATCHDOG_MS, and a start with time to spare
    print("unix: HEARTBEAT %.2f s after the loop hung" % (back - hung))

    assert param(m, "SIM_SPEED").param_value == 8.5
    got = MissionClient(m).download()
    assert got is not None and same(got, items)
    v.stop()
    assert v.proc.returncode == 0
    assert v.output().count("watchdog: no feed for 2000 ms: starting the vehicle again") == 1


@pytest.mark.parametrize("fault, args", [(1, ()), (2, ("--set", "watchdog_ms=1000"))],
                         ids=["raising", "hanging"])
def test_three_resets_start_safe_mode_until_a_clean_run(watched, fault, args):
    v = watched("--set", "clean_run_ms=4000", *args)
    m = v.gcs()
    assert param(m, "SIM_SPEED", 6.5).param_value == 6.5
    assert ints(param(m, "APP_FAULT", bits(fault), INT32).param_value) == fault
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    assert run(m, PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0  # acknowledged: it does not count

    # The start fails (in place), and twice more after the watchdog starts it again;
    # the third time it starts in safe mode, and says so every second.
    assert safe_texts(m, 30.0, until=1) == 1, v.output()
    assert safe_texts(m, 2.2) >= 2
    assert recv(m, "ATTITUDE", 1.0) is None  # no application, no streams
    assert MissionClient(m, timeout=0.3, retries=1).download() is None  # no missions
    assert param(m, "SIM_SPEED").param_value == 6.5

    # The ground station puts the parameter right; after the clean run the texts stop.
    assert ints(param(m, "APP_FAULT", bits(0), INT32).param_value) == 0
    assert run(m, PREFLIGHT_STORAGE, 1.0) == 0
    time.sleep(1.0)
    assert safe_texts(m, 1.5) == 0
    assert run(m, PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0

    # The next start is a normal one: the application and every service.
    assert listen(m, "ATTITUDE", 10.0) is not None
    assert safe_texts(m, 1.5) == 0
    v.stop()
    out = v.output()
    assert v.proc.returncode == 0
    ended = out.count("watchdog: the vehicle ended (status 1): starting it again")
    hung = out.count("watchdog: no feed for 1000 ms: starting the vehicle again")
    assert (ended, hung) == ((3, 0) if fault == 1 else (0, 3)), out
    assert out.count("mavstack: " + SAFE_TEXT) == 1


def test_acknowledged_reboots_do_not_count(watched):
    v = watched()
    m = v.gcs()
    for _ in range(4):
        assert run(m, PREFLIGHT_REBOOT_SHUTDOWN, 1.0) == 0
        assert heartbeat(m, 10.0) is not None
    assert listen(m, "ATTITUDE", 3.0) is not None
    assert safe_texts(m, 1.5) == 0
    v.stop()
    assert "starting" not in v.output()


def test_a_ctrl_c_stops_the_vehicle_cleanly_and_its_watchdog_with_it(watched):
    v = watched()
    v.gcs()
    v.proc.send_signal(signal.SIGINT)  # as a Ctrl-C at the terminal, to the watchdog alone
    assert v.proc.wait(10) == 0
    assert "watchdog:" not in v.output()


def test_a_vehicle_that_never_fed_it_is_not_started_again():
    r = subprocess.run([PYTHON, WATCHDOG, "--no-such-option"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "unknown argument: --no-such-option" in r.stdout + r.stderr
    assert "watchdog:" not in r.stdout


def test_without_its_watchdog_the_unix_vehicle_counts_nothing(vehicle, tmp_path):
    """`make run`: no watchdog process, so no restarts to count: killed four times, the
    vehicle starts a fifth with every service, and keeps no count."""
    for _ in range(4):
        v = vehicle()
        v.gcs()
        v.stop(signal.SIGKILL)
    m = vehicle().gcs()
    assert listen(m, "ATTITUDE", 3.0) is not None
    assert not os.path.exists(tmp_path / "storage" / "boot")


# --- the guard on CPython (conftest puts firmware/ on the path) ----------------------

class _Endpoint:
    def __init__(self, storage):
        self.storage = storage
        self.now = 1000
        self.texts = []

    def statustext(self, severity, text):
        self.texts.append((severity, bytes(text)))

    def setting(self, name, default):
        return default


def _storages(tmp_path):
    from mavstack.storage import Storage
    from mavstack.storage_ram import RamStorage

    return [Storage(str(tmp_path / "files")), RamStorage(bytearray(4096))]


@pytest.mark.parametrize("kind", ["files", "ram"])
def test_the_guard_counts_unclean_starts(tmp_path, kind):
    from mavstack.storage import sealed
    from mavstack.watchdog import Guard

    storage = _storages(tmp_path)[kind == "ram"]
    services = ("status", "params", "commands", "missions", "streams")

    def count():
        """The count in the file: the starts so far that did not end cleanly."""
        try:
            f = storage.open("boot")
        except OSError:
            return 0
        record = f.read()
        f.close()
        return record[0] if sealed(record, 3) else 0

    def start():
        g = Guard(services)
        ep = _Endpoint(storage)
        g.attach(ep)
        return g, ep

    for n in range(3):  # three starts that end without a clean end
        g, ep = start()
        assert (g.safe, g.services, count()) == (False, services, n + 1)
    g, ep = start()
    assert (g.safe, g.services, count()) == (True, ("status", "params", "commands"), 4)
    g.tick(1000)
    g.tick(1500)
    g.tick(2000)
    assert ep.texts == [(2, SAFE_TEXT.encode())] * 2
    assert len(g.text) <= 50
    g.tick(1000 + 60000)  # the clean minute: the count starts again, the texts stop
    g.tick(1000 + 62000)
    assert len(ep.texts) == 3
    assert count() == 0
    g, ep = start()
    assert (g.safe, count()) == (False, 1)
    g.stop()  # a clean end
    assert count() == 0
    # A broken record counts as none.
    f = storage.open_new("boot", 3)
    f.write(b"\x07\x00\x00")
    f.close()
    storage.commit("boot")
    assert count() == 0


def test_the_guard_keeps_counting_past_safe_mode_up_to_255(tmp_path):
    from mavstack.storage_ram import RamStorage
    from mavstack.watchdog import Guard

    storage = RamStorage(bytearray(4096))
    for _ in range(300):
        g = Guard(("status", "inputs", "commands"))
        g.attach(_Endpoint(storage))
    assert g.services == ("status", "commands")
    assert g.text == b"Safe mode after 255 resets: status,commands"
