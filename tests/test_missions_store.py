"""The flash-backed plan store (mavstack/services/missions/store.py): records, two slots, atomic
commit, corruption detection; and the exact float <-> fixed-point conversions of the
seed's MISSION_ITEM. The kill test commits plans on MicroPython and SIGKILLs it at
random moments, then boots the store after each kill."""
import os
import random
import signal
import struct
import subprocess
import time
from fractions import Fraction

from hypothesis import given, settings, strategies as st

from conftest import FIRMWARE, MICROPYTHON, ROOT, run_mpy
from mavstack.services.missions.store import HEADER_SIZE, RECORD_SIZE, MissionStore
from mavstack import fields as service
from mavstack.storage import Storage

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")


def record(k, i, command=16):
    rec = bytearray(RECORD_SIZE)
    struct.pack_into("<ffffiifHBB", rec, 0, k, i, 0, 0, 473977420 + i, 85455940, 10.0, command, 3, 1)
    return rec


def commit(store, k, n, command=16):
    store.begin()
    for i in range(n):
        assert store.put(i, record(k, i, command))
    assert store.seal(n)
    assert store.commit()


def contents(store):
    rec = bytearray(RECORD_SIZE)
    out = []
    for i in range(store.count):
        assert store.read(i, rec)
        out.append(struct.unpack_from("<ff", rec, 0))
    return out


def open_store(path, capacity=500):
    return MissionStore(Storage(str(path)), "mission", 0, capacity)


def test_commit_read_reopen(tmp_path):
    s = open_store(tmp_path)
    assert (s.count, s.corrupt) == (0, False)
    commit(s, 1, 10)
    id1 = s.plan_id
    commit(s, 2, 3)
    assert contents(s) == [(2.0, float(i)) for i in range(3)]
    assert s.plan_id not in (id1, 0)
    assert not s.read(3, bytearray(RECORD_SIZE))
    s.close()
    s = open_store(tmp_path)
    assert contents(s) == [(2.0, float(i)) for i in range(3)] and not s.corrupt
    assert s.gen == 2


def test_staging_never_shows(tmp_path):
    s = open_store(tmp_path)
    commit(s, 1, 5)
    s.begin()
    for i in range(8):
        s.put(i, record(2, i))
    assert contents(s) == [(1.0, float(i)) for i in range(5)]  # the plan in force meanwhile
    s.close()
    s = open_store(tmp_path)  # killed before the commit
    assert contents(s) == [(1.0, float(i)) for i in range(5)] and not s.corrupt
    s.begin(keep=5)  # a partial write starts from a copy
    s.put(2, record(3, 2))
    assert s.seal(5) and s.commit()
    assert [k for k, _ in contents(s)] == [1.0, 1.0, 3.0, 1.0, 1.0]


def test_jump_count(tmp_path):
    s = open_store(tmp_path)
    s.begin()
    for i, c in enumerate((16, 177, 16, 177, 177)):
        s.put(i, record(0, i, c))
    assert s.seal(5) and s.staged_jumps == 3


def _slot_files(path):
    return [os.path.join(str(path), "mission.%d" % i) for i in (0, 1)]


def _active(path):
    """The slot file holding the newest committed header."""
    best, gen = None, -1
    for f in _slot_files(path):
        data = open(f, "rb").read(HEADER_SIZE)
        if len(data) == HEADER_SIZE and data[:4] == b"MSN\x01":
            g = struct.unpack_from("<I", data, 8)[0]
            if g > gen:
                best, gen = f, g
    return best


def _damage(f, offset):
    with open(f, "r+b") as fh:
        fh.seek(offset)
        b = fh.read(1)
        fh.seek(offset)
        fh.write(bytes([b[0] ^ 0x40]))


def test_corrupt_records_detected_and_wiped(tmp_path):
    s = open_store(tmp_path)
    commit(s, 1, 5)
    commit(s, 2, 5)
    s.close()
    _damage(_active(tmp_path), HEADER_SIZE + 3 * RECORD_SIZE + 1)
    s = open_store(tmp_path)
    # Not the older plan: the operator replaced it. Empty, and said so.
    assert s.corrupt and s.count == 0
    commit(s, 3, 2)
    s.close()
    s = open_store(tmp_path)
    assert not s.corrupt and contents(s) == [(3.0, 0.0), (3.0, 1.0)]


def test_corrupt_header_garbage_and_truncation(tmp_path):
    for how in ("header", "garbage", "truncate"):
        d = tmp_path / how
        s = open_store(d)
        commit(s, 1, 20)
        s.close()
        f = _active(d)
        if how == "header":
            _damage(f, 7)
        elif how == "garbage":
            open(f, "wb").write(bytes(random.Random(1).randrange(256) for _ in range(3000)))
        else:
            os.truncate(f, HEADER_SIZE + 5 * RECORD_SIZE)
        s = open_store(d)
        assert s.corrupt and s.count == 0, how


def test_damaged_older_slot_is_harmless(tmp_path):
    s = open_store(tmp_path)
    commit(s, 1, 5)
    commit(s, 2, 5)
    s.close()
    older = [f for f in _slot_files(tmp_path) if f != _active(tmp_path)][0]
    _damage(older, HEADER_SIZE + 2)
    s = open_store(tmp_path)
    assert not s.corrupt and contents(s) == [(2.0, float(i)) for i in range(5)]


def test_corrupt_store_reported_by_statustext(tmp_path):
    from mission_rig import Rig

    r = Rig(tmp_path, services=("status", "missions"))
    from mission_gcs import plan

    assert r.upload(plan(4)) == 0
    for s in r.missions.stores:
        s.close()
    _damage(_active(tmp_path / "st"), HEADER_SIZE + 5)
    r2 = Rig(tmp_path, services=("status", "missions"))
    r2.run(3000)
    texts = [t.text for t in r2.take("STATUSTEXT")]
    assert any("mission plan corrupt" in t for t in texts), texts
    assert r2.download() == []


# --- MISSION_ITEM's float degrees and MISSION_ITEM_INT's integers ------------------
# The service converts in place, in the record's bytes (mission_items.fix, mission_items.unfix:
# small ints only, for 32-bit boards); these wrap them as int -> int functions.
NOT_A_NUMBER = None


def to_fixed(b, scale_e):
    """float32 bytes b (degrees, or metres where scale_e is 4) -> the int32, NOT_A_NUMBER
    for NaN, infinities and values beyond int32 (the field is then 0)."""
    rec = bytearray(b)
    if not service.fix(rec, 0, scale_e == 4):
        assert rec == bytes(4)
        return NOT_A_NUMBER
    return struct.unpack("<i", rec)[0]


def to_float(v, scale_e):
    """int32 v -> the bits of the float32 the service sends for it."""
    buf = bytearray(struct.pack("<i", v))
    service.unfix(buf, 0, scale_e == 4)
    return struct.unpack("<I", buf)[0]


def _exact(bits):
    return Fraction(struct.unpack("<f", struct.pack("<I", bits))[0])


def _nearest(q):
    """round(q), halves away from zero, on an exact Fraction."""
    n = abs(q)
    r = int(n + Fraction(1, 2))
    return r if q >= 0 else -r


@settings(max_examples=1000, deadline=None)
@given(st.integers(0, 0xFFFFFFFF), st.sampled_from([7, 4]))
def test_float_to_fixed_is_exact(bits, scale_e):
    got = to_fixed(struct.pack("<I", bits), scale_e)
    e = (bits >> 23) & 0xFF
    if e == 0xFF:
        assert got == NOT_A_NUMBER
        return
    want = _nearest(_exact(bits) * 10 ** scale_e)
    if abs(want) > 0x7FFFFFFF:
        assert got == NOT_A_NUMBER
    else:
        assert got == want


def test_float_to_fixed_every_exponent():
    """Every exponent (subnormals, the int32 limits, NaN), the mantissa's edges, both signs."""
    for scale_e in (7, 4):
        for e in range(256):
            for m in (0, 1, 0x400000, 0x7FFFFF, 0x2AAAAA, 0x555555):
                for sign in (0, 0x80000000):
                    bits = sign | e << 23 | m
                    got = to_fixed(struct.pack("<I", bits), scale_e)
                    if e == 0xFF:
                        assert got == NOT_A_NUMBER
                        continue
                    want = _nearest(_exact(bits) * 10 ** scale_e)
                    assert got == (NOT_A_NUMBER if abs(want) > 0x7FFFFFFF else want), (hex(bits), scale_e)


def test_float_to_fixed_examples():
    for deg in (47.397742, -122.4194, 180.0, -180.0, 90.0, 0.0, 1e-9, 214.7483647):
        b = struct.pack("<f", deg)
        f = struct.unpack("<f", b)[0]
        got = to_fixed(b, 7)
        if abs(f) * 1e7 < 2 ** 31:
            assert got == round(Fraction(f) * 10 ** 7)


@settings(max_examples=1000, deadline=None)
@given(st.integers(-0x80000000, 0x7FFFFFFF), st.sampled_from([7, 4]))
def test_fixed_to_float_is_correctly_rounded(v, scale_e):
    bits = to_float(v, scale_e)
    if v == 0x7FFFFFFF:  # INT32_MAX: x or y unset, NaN in the seed's MISSION_ITEM
        assert bits == 0x7FC00000
        return
    want = Fraction(v, 10 ** scale_e)
    got = _exact(bits)
    # No float32 lies closer to v / 10**scale_e (ties: the even one).
    for nb in (bits - 1, bits + 1):
        if 0 <= nb <= 0xFFFFFFFF and (nb >> 23) & 0xFF != 0xFF:
            other = _exact(nb)
            assert abs(got - want) <= abs(other - want)
            if abs(got - want) == abs(other - want):
                assert bits & 1 == 0
    if v == 0:
        assert bits == 0


def test_seed_coordinates_round_trip():
    """A ground station's float32 degrees go in and come out bit for bit."""
    rng = random.Random(5)
    for _ in range(20000):
        lat = struct.unpack("<f", struct.pack("<f", rng.uniform(-90, 90)))[0]
        if abs(lat) < 1:  # below 1 degree float32 is finer than 1e-7: no longer a round trip
            continue
        fixed = to_fixed(struct.pack("<f", lat), 7)
        assert struct.unpack("<f", struct.pack("<I", to_float(fixed, 7)))[0] == lat


FLOATS = (47.397742, -8.545594, 179.99999, -0.000123, 1e-30, 3e9, -122.4, 151.2, 179.9, -180.0, 214.74)
FIXED = (473977420, -85455940, 1, -1, 2147483647, -2147483648, 0, -1224000000, 1512000000, 1799000000)


def test_conversions_agree_on_micropython():
    code = (
        "import struct\n"
        "from mavstack import fields as m\n"
        "out = []\n"
        "for v in %r:\n"
        "    for local in (False, True):\n"
        "        b = bytearray(struct.pack('<f', v))\n"
        "        ok = m.fix(b, 0, local)\n"
        "        out.append(struct.unpack('<i', b)[0] if ok else None)\n"
        "for v in %r:\n"
        "    for local in (False, True):\n"
        "        b = bytearray(struct.pack('<i', v))\n"
        "        m.unfix(b, 0, local)\n"
        "        out.append(struct.unpack('<I', b)[0])\n"
        "print(out)\n" % (FLOATS, FIXED)
    )
    r = run_mpy(code)
    assert r.returncode == 0, r.stderr
    want = [to_fixed(struct.pack("<f", v), k) for v in FLOATS for k in (7, 4)]
    want += [to_float(v, k) for v in FIXED for k in (7, 4)]
    assert r.stdout.strip() == str(want)


# --- killed at random moments while committing ---------------------------------

def _check_after_kill(path, last, size):
    """The store boots clean with plan `last` or the one after it, whole."""
    s = open_store(path)
    try:
        assert not s.corrupt
        got = contents(s)
    finally:
        s.close()
    if not got:
        assert last < 0
        return -1
    k = int(got[0][0])
    assert k in (last, last + 1), (k, last)
    assert got == [(float(k), float(i)) for i in range(size(k))], "plan %d is not whole" % k
    return k


def test_killed_at_random_points(tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location("commit_loop_size", os.path.join(TESTS_MPY, "missions_commit_loop.py"))
    source = open(spec.origin).read()
    size = lambda k: 5 + (37 * k) % 150  # noqa: E731 (as in the script)
    assert "5 + (37 * k) % 150" in source
    env = dict(os.environ, MICROPYPATH=os.pathsep.join([FIRMWARE, ".frozen"]))
    rng = random.Random(20240611)
    path = tmp_path / "st"
    last = -1
    kills = mid = 0
    deadline = time.time() + 60
    while kills < 60 and time.time() < deadline:
        p = subprocess.Popen([MICROPYTHON, os.path.join(TESTS_MPY, "missions_commit_loop.py"), str(path)],
                             env=env, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        head = b""
        if rng.random() < 0.8:  # most kills while committing, some while booting
            head = p.stdout.readline()
        time.sleep(rng.uniform(0.0, 0.03))
        p.send_signal(signal.SIGKILL)
        out, err = p.communicate()
        out = head + out
        kills += 1
        lines = out.decode().split()
        assert b"Error" not in err, err
        committed = [int(lines[i + 1]) for i, w in enumerate(lines) if w == "committed" and i + 1 < len(lines)]
        if committed:
            mid += 1
            last = committed[-1]
        last = _check_after_kill(path, last, size)
    assert kills >= 50 and mid >= 30, (kills, mid)
    # And the firmware boots with what is left.
    r = run_mpy("from mavstack.services.missions.store import MissionStore\nfrom mavstack.storage import Storage\n"
                "s = MissionStore(Storage(%r), 'mission', 0, 500)\nprint(s.corrupt, s.count)\n" % str(path))
    assert r.returncode == 0 and r.stdout.split()[0] == "False", r.stdout + r.stderr
