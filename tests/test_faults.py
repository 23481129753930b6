"""Fault injection: a lossy, duplicating and reordering link (UDP and a pty), kill -9 in the
middle of every kind of write, and storage that is full or read-only.

- Over the bad link a parameter download, mission uploads and downloads and commands end
  correct or cleanly cancelled, never silently corrupt: what the ground station believes
  is held against what the vehicle holds, read over a second, clean link.
- More than 200 kill -9s of MicroPython processes saving parameters, committing missions
  and writing signing keys and timestamps (tests/mpy/*_loop.py): after each, the stored
  data is the old or the new, never a mix or corrupt.
- With storage full (RLIMIT_FSIZE: writes fail with EFBIG) or read-only (a read-only bind
  mount where the tests run as root, else chmod), saves are refused with a STATUSTEXT
  and a NACK, and the vehicle carries on in memory.
"""
import math
import os
import random
import resource
import signal
import struct
import subprocess
import sys
import time

import pytest

from conftest import FIRMWARE, MICROPYTHON, ROOT, Vehicle, free_udp_port, recv
from fault_gcs import Gcs
from lossy_world import items_for, outcome_holds, same_items
from pty_relay import PtyRelay
from relay import LossyRelay

from pymavlink import mavutil

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")
BOARDS = os.path.join(ROOT, "boards")
sys.path.insert(0, BOARDS)


# --- the lossy link ------------------------------------------------------------------

class BadLink:
    """A vehicle with a bad link (UDP through LossyRelay, or a pty through PtyRelay) and a
    clean udpin link to check what it holds."""

    def __init__(self, kind, storage, rate=0.2, seed=1):
        self.kind = kind
        clean = free_udp_port()
        if kind == "udp":
            port = free_udp_port()
            self.relay = LossyRelay(port, rate=rate, delay=(0.001, 0.03), seed=seed)
            links = ["udpin:127.0.0.1:%d" % port, "udpin:127.0.0.1:%d" % clean]
        else:
            self.relay = PtyRelay(rate=rate, seed=seed)
            links = ["serial:%s:115200" % self.relay.vehicle_dev, "udpin:127.0.0.1:%d" % clean]
        self.v = Vehicle(storage, links=links, args=["--set", "application=0"]).start()
        self.clean = Gcs(self.v.gcs(port=clean, source_system=250), tries=4)
        if kind == "udp":
            m = mavutil.mavlink_connection("udpout:127.0.0.1:%d" % self.relay.port, source_system=255,
                                           source_component=190, dialect="common")
        else:
            m = mavutil.mavlink_connection(self.relay.gcs_dev, baud=115200, source_system=255,
                                           source_component=190, dialect="common")
        m.mav.heartbeat_send(6, 8, 0, 0, 0)
        self.bad = Gcs(m)

    def close(self):
        self.bad.m.close()
        self.v.stop()
        self.relay.close()


@pytest.fixture(params=["udp", "pty"])
def badlink(request, tmp_path):
    b = BadLink(request.param, tmp_path / "storage", seed=7)
    yield b
    b.close()


def test_lossy_parameter_download(badlink):
    values = badlink.bad.param_list()
    truth = badlink.clean.param_list()
    assert truth is not None
    if values is not None:  # complete, so it must be exactly right
        assert values.keys() == truth.keys()
        for name in truth:
            assert values[name] == truth[name] or (math.isnan(values[name]) and math.isnan(truth[name])), name
    assert values is not None, "parameter list never completed over the bad link: %r" % badlink.relay.stats


def test_lossy_mission_upload_and_download(badlink):
    outcomes = []
    old = badlink.clean.download()
    assert old == []
    for round_ in range(3):
        new = items_for(100 * round_ + 1, 3 + 2 * round_)
        outcome = badlink.bad.upload(new)
        stored = badlink.clean.download()
        outcomes.append(outcome)
        assert outcome_holds(outcome, stored, new, old), (round_, outcome, stored)
        old = stored
        got = badlink.bad.download()
        if got is not None:  # complete: exactly the stored plan
            assert same_items(got, stored), (round_, got, stored)
    assert "accepted" in outcomes, (outcomes, badlink.relay.stats)
    assert badlink.relay.stats["dropped"] and badlink.relay.stats["duplicated"] and badlink.relay.stats["delayed"]


def test_lossy_commands(badlink):
    accepted = 0
    for k in range(6):
        value = 1.0 + k
        got = badlink.clean.param("SIM_ACCEL")
        before = got.param_value
        # DO_SET_PARAMETER: param1 the index, param2 the value.
        result = badlink.bad.command(180, got.param_index, value)
        after = badlink.clean.param("SIM_ACCEL").param_value
        if result == 0:
            accepted += 1
            assert after == value, (k, after, value)
        elif result is None:
            assert after in (before, value), (k, after)
        else:
            assert after == before, (k, result, after)
    assert accepted >= 3, (accepted, badlink.relay.stats)


# --- kill -9 -------------------------------------------------------------------------

def _spawn(script, storage):
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join([TESTS_MPY, FIRMWARE, BOARDS, ".frozen"])
    return subprocess.Popen([MICROPYTHON, os.path.join(TESTS_MPY, script), storage], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def kill_loop(script, storage, kills, check, rng, most_s=0.05):
    """Start script, let it write for a random time, kill -9, check; `kills` times."""
    done = 0
    last = None
    while done < kills:
        proc = _spawn(script, storage)
        first = proc.stdout.readline()
        assert first.startswith("start"), first + proc.stdout.read()
        time.sleep(rng.uniform(0, most_s))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        # Whole lines only: the kill may cut the last one short ("committed 1" of "committed 12").
        out = (first + proc.stdout.read()).split("\n")[:-1]
        assert not [line for line in out if "Traceback" in line or "failed" in line], out[-5:]
        last = check(storage, out, last)
        done += 1
    return done


def _last(out, word):
    vals = [int(line.split()[1]) for line in out if line.startswith(word + " ")]
    return vals[-1] if vals else None


def check_params(storage, out, last):
    from mavstack.services.params import table as param_table
    import unix_params

    start = _last(out, "start")
    saved = _last(out, "saved")
    done = saved if saved is not None else start  # the last set known to be stored
    path = os.path.join(storage, "params")
    if not os.path.exists(path):
        assert done == 0, out[-3:]
        return 0
    with open(path, "rb") as f:
        data = f.read()
    t = param_table.ParamTable(unix_params.PARAMS)
    assert t.unpack(data, len(data)) == 0, "stored parameters corrupt after kill -9"
    t.adopt(t._loaded)
    k = t.get("BRD_SERIAL_NUM")
    assert k in (done, done + 1), (k, done)
    if k:
        assert t.get("SYSID_MYGCS") == k % 255 + 1, "a mix of two saves"
        assert math.isclose(t.get("SIM_SPEED"), 0.5 + (k % 290) / 10, rel_tol=1e-6), "a mix of two saves"
    return k


def check_missions(storage, out, last):
    from mavstack.services.missions.store import MissionStore, RECORD_SIZE
    from mavstack.storage import Storage

    start = _last(out, "start")
    committed = _last(out, "committed")
    store = MissionStore(Storage(storage), "mission", 0, 500)
    try:
        assert not store.corrupt, "mission store corrupt after kill -9"
        rec = bytearray(RECORD_SIZE)
        if store.count == 0:
            assert committed is None and start == 0, out[-3:]
            return -1
        ks = set()
        for i in range(store.count):
            assert store.read(i, rec)
            p1, p2 = struct.unpack_from("<ff", rec, 0)
            ks.add(int(p1))
            assert int(p2) == i, "item %d holds %d" % (i, p2)
        assert len(ks) == 1, "a plan made of two commits: %s" % sorted(ks)
        k = ks.pop()
        assert store.count == 5 + (37 * k) % 150, "count of another plan"
        done = committed if committed is not None else start - 1
        assert k in (done, done + 1), (k, done)
        return k
    finally:
        store.close()


def check_signing(storage, out, last):
    from mavstack.storage import checksum

    start = _last(out, "start")
    keyed = _last(out, "key")
    done = keyed if keyed is not None else start
    ts_printed = [int(line.split()[1]) for line in out if line.startswith("ts ")]
    path = os.path.join(storage, "signing_key")
    if not os.path.exists(path):
        assert done == 0, out[-3:]
        return None
    with open(path, "rb") as f:
        data = f.read()
    assert len(data) == 42 and checksum(data[:40]) == data[40] | data[41] << 8, "signing key file corrupt"
    k = struct.unpack_from("<I", data, 0)[0] - 1
    assert all(b == k & 0xFF for b in data[4:32]), "a key mixed of two writes"
    assert k in (done, done + 1), (k, done)
    ts = int.from_bytes(data[32:38], "little")
    if k == done and ts_printed:
        assert ts >= ts_printed[-1], "stored timestamp went back: %d < %d" % (ts, ts_printed[-1])
    if last is not None:
        assert ts >= last, "stored timestamp went back across a restart: %d < %d" % (ts, last)
    return ts


def test_kill_9_during_writes(tmp_path):
    rng = random.Random(9)
    kills = 0
    kills += kill_loop("params_save_loop.py", str(tmp_path / "params"), 70, check_params, rng)
    kills += kill_loop("missions_commit_loop.py", str(tmp_path / "missions"), 70, check_missions, rng)
    kills += kill_loop("signing_save_loop.py", str(tmp_path / "signing"), 70, check_signing, rng)
    assert kills >= 200


# --- storage full and read-only ------------------------------------------------------

def _full():
    # Every write fails with EFBIG, as on a full medium: RLIMIT_FSIZE 0, SIGXFSZ ignored.
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


class FaultyVehicle(Vehicle):
    """The unix vehicle with its storage full ("full") or read-only ("readonly")."""

    def __init__(self, storage, fault, **kw):
        Vehicle.__init__(self, storage, **kw)
        self.fault = fault

    def start(self):
        cmd = [MICROPYTHON, os.path.join(FIRMWARE, "main.py"), "--board", self.board, "--storage", self.storage]
        for link in self.links:
            cmd += ["--link", link]
        cmd += self.args
        preexec = None
        if self.fault == "full":
            preexec = _full
        elif os.geteuid() == 0:
            # root writes through chmod: a read-only bind mount in a mount namespace of its own.
            script = 'mount --bind "$0" "$0" && mount -o remount,bind,ro "$0" "$0" && exec "$@"'
            cmd = ["unshare", "-m", "sh", "-c", script, self.storage] + cmd
        else:
            for dirpath, _, files in os.walk(self.storage):
                for name in files:
                    os.chmod(os.path.join(dirpath, name), 0o444)
                os.chmod(dirpath, 0o555)
        env = dict(os.environ)
        env["MICROPYPATH"] = os.pathsep.join([FIRMWARE, BOARDS, ".frozen"])
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, preexec_fn=preexec)
        return self


OLD_PLAN = items_for(7, 2)


@pytest.fixture(scope="module")
def populated(tmp_path_factory):
    """A storage with SIM_ACCEL = 4 saved and a two-item mission."""
    storage = tmp_path_factory.mktemp("populated") / "storage"
    v = Vehicle(storage, args=["--set", "application=0"]).start()
    try:
        g = Gcs(v.gcs())
        g.m.mav.param_set_send(1, 1, b"SIM_ACCEL", 4.0, 9)
        assert g.command(245, 1) == 0  # PREFLIGHT_STORAGE: save
        assert g.upload(OLD_PLAN) == "accepted"
    finally:
        v.stop()
    return storage


@pytest.fixture
def faulty(populated, tmp_path):
    """faulty(mode) -> (vehicle, Gcs) on a copy of the populated storage, full or read-only."""
    import shutil

    started = []

    def start(mode):
        storage = tmp_path / "storage"
        shutil.copytree(populated, storage)
        v = FaultyVehicle(storage, mode, args=["--set", "application=0", "--set", "param_autosave_ms=300"])
        started.append(v)
        v.start()
        return v, Gcs(v.gcs())

    yield start
    for v in started:
        v.stop()
        if v.fault == "readonly" and os.geteuid() != 0:
            for dirpath, _, files in os.walk(v.storage):
                os.chmod(dirpath, 0o755)
                for name in files:
                    os.chmod(os.path.join(dirpath, name), 0o644)


def _texts(g, seconds):
    out = []
    deadline = time.time() + seconds
    while time.time() < deadline:
        m = g.recv(("STATUSTEXT",), timeout=deadline - time.time())
        if m is not None:
            out.append(m.text)
    return out


def _still_working(v, g):
    v.check_alive()
    assert recv(g.m, "HEARTBEAT", timeout=3) is not None
    assert g.param("SIM_SPEED") is not None
    assert same_items(g.download(), OLD_PLAN)


@pytest.mark.parametrize("mode", ["full", "readonly"])
def test_storage_fault_save_command_fails(faulty, mode):
    v, g = faulty(mode)
    g.drain()
    assert g.command(245, 1) == 4  # PREFLIGHT_STORAGE save -> MAV_RESULT_FAILED
    texts = _texts(g, 1.0)
    assert any("not saved" in t for t in texts), texts
    _still_working(v, g)


@pytest.mark.parametrize("mode", ["full", "readonly"])
def test_storage_fault_mission_upload_refused(faulty, mode):
    v, g = faulty(mode)
    assert g.upload(items_for(55, 3)) == "refused"
    _still_working(v, g)  # the old plan, still served


@pytest.mark.parametrize("mode", ["full", "readonly"])
def test_storage_fault_param_set_reported_and_kept_in_memory(faulty, mode):
    v, g = faulty(mode)
    g.drain()
    g.m.mav.param_set_send(1, 1, b"SIM_ACCEL", 5.0, 9)
    texts = _texts(g, 1.5)  # the autosave falls due and fails
    assert any("not saved" in t for t in texts), texts
    assert g.param("SIM_ACCEL").param_value == 5.0  # in force, though not stored
    _still_working(v, g)
