"""MAVLink 2 signing: the SHA-256 kernels (viper, portable) against hashlib on every runtime, the signing
service in-process with pymavlink (with its secret key) as the ground station and
oracle, key persistence, and signed traffic under heap_lock() on MicroPython."""
import hashlib
import os
import random
import sys
import time

import pytest

from conftest import ROOT, recv, run_mpy

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")
if TESTS_MPY not in sys.path:
    sys.path.insert(0, TESTS_MPY)

from harness import Bench  # noqa: E402
from pymavlink.dialects.v20 import common as mav2  # noqa: E402

from mavstack import endpoint  # noqa: E402
from mavstack.parser import Parser  # noqa: E402
from mavstack.kernels.sha256 import Sha256  # noqa: E402

KEY = bytes(range(1, 33))
EPOCH_2015_US = 1420070400000000

SHA_SCRIPT = """
import sys
import time
from binascii import hexlify, unhexlify
from mavstack.kernels.sha256 import Sha256, SHA256_IMPL
h = Sha256()
out = bytearray(32)
print(SHA256_IMPL)
for line in open(sys.argv[1]):
    hx, cut = line.split()
    data = unhexlify(hx) if hx != "-" else b""
    cut = int(cut)
    h.update(data, 0, cut)
    h.update(data, cut, len(data))
    h.digest_into(out)
    print(hexlify(out).decode())
"""


def sha_cases(n=400):
    rnd = random.Random(256)
    sizes = list(range(0, 130)) + [rnd.randint(0, 1000) for _ in range(n - 130)]
    return [(rnd.randbytes(s), rnd.randint(0, s)) for s in sizes]


@pytest.mark.parametrize("portable", [False, True], ids=["mpy-viper", "mpy-portable"])
def test_sha256_on_micropython_matches_hashlib(tmp_path, monkeypatch, portable):
    cases = sha_cases()
    src = tmp_path / "cases.txt"
    src.write_text("".join("%s %d\n" % (d.hex() or "-", c) for d, c in cases))
    script = tmp_path / "sha.py"
    script.write_text(SHA_SCRIPT)
    if portable:
        monkeypatch.setenv("MAVSTACK_PORTABLE", "1")
    else:
        monkeypatch.delenv("MAVSTACK_PORTABLE", raising=False)
    r = run_mpy(str(script), src)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.split()
    assert lines[0] == ("portable" if portable else "viper")
    assert lines[1:] == [hashlib.sha256(d).hexdigest() for d, _ in cases]


def test_sha256_on_cpython_matches_hashlib():
    h = Sha256()
    out = bytearray(32)
    for data, cut in sha_cases():
        h.update(data, 0, cut)
        h.update(data, cut, len(data))
        h.digest_into(out)
        assert bytes(out) == hashlib.sha256(data).digest()


# --- the service in-process, pymavlink as the ground station ------------------------

class Gcs:
    """A pymavlink MAVLink 2 station on the bench's in-memory link; out: raw vehicle bytes."""

    def __init__(self, bench, key=None, link_id=0, timestamp=1000):
        self.b = bench
        self.mav = mav2.MAVLink(None, srcSystem=255, srcComponent=190)
        self.out = bytearray()
        self.sig = []  # (link id, timestamp) of every signed vehicle frame, in order
        self.unsigned = 0
        self._rx = Parser(bench.dialect.CRC_LEN, self._on_frame)
        if key is not None:
            self.use_key(key, link_id, timestamp)

    def use_key(self, key, link_id=0, timestamp=1000):
        s = self.mav.signing
        s.secret_key = key
        s.sign_outgoing = True
        s.link_id = link_id
        s.timestamp = timestamp

    def send(self, msg):
        f = bytearray(msg.pack(self.mav))
        self.b.send_raw(f)
        return f

    def run(self, n=1, step_ms=1):
        b = self.b
        buf = bytearray(4096)
        for _ in range(n):
            b.now += step_ms
            b.ep.poll(b.now)
            k = b.gcs_end.readinto(buf)
            self.out += buf[:k]
            self._rx.feed(buf, k)

    def _on_frame(self, msgid, payload):
        rx = self._rx
        if rx.signed:
            s = rx.signature
            self.sig.append((s[0], int.from_bytes(bytes(s[1:7]), "little")))
        else:
            self.unsigned += 1

    def received(self):
        """pymavlink's parse of everything the vehicle sent since the last call."""
        msgs = self.mav.parse_buffer(bytes(self.out)) or []
        self.out.clear()
        return msgs


def bench(storage=None, board=None, **kw):
    b = Bench(services=("signing", "status"), storage=str(storage) if storage else None,
              board=board, **kw)
    return b, b.ep.services["signing"]


def delivered(b):
    """Message ids the endpoint dispatched (PING/HEARTBEAT/COMMAND_LONG), recorded in a list."""
    seen = []
    for msgid in (0, 4, 76):
        b.ep.on(msgid, lambda link, p, msgid=msgid: seen.append(msgid))
    return seen


def texts(msgs):
    return [m.text for m in msgs if m.get_type() == "STATUSTEXT"]


def setup_signing(g, key=KEY, initial=0, target=1):
    g.send(g.mav.setup_signing_encode(target, 1, key, initial))
    g.run(3)


def test_setup_signing_then_signed_frames_verified_both_ways(tmp_path):
    b, svc = bench(tmp_path / "st")
    g = Gcs(b)
    assert b.ep.links[0].rx.verify is None and b.ep.links[0].tx.sign is None
    setup_signing(g)
    assert svc.enabled
    assert "Signing on" in texts(g.received())
    g.unsigned = 0  # frames from before the key
    seen = delivered(b)
    g.use_key(KEY, link_id=3, timestamp=5000)
    for i in range(20):
        g.send(g.mav.ping_encode(1000 + i, i, 0, 0))
        g.run(2)
    g.run(1500)
    msgs = g.received()
    pings = [m for m in msgs if m.get_type() == "PING"]
    assert [m.seq for m in pings] == list(range(20))
    assert seen.count(4) == 20 and svc.accepted == 20
    assert {"HEARTBEAT", "SYS_STATUS"} <= {m.get_type() for m in msgs}
    s = g.mav.signing
    assert s.goodsig_count == len(msgs) > 20
    assert s.badsig_count == 0 and s.unsigned_count == 0 and s.reject_count == 0
    # Link id is the link's index; the timestamp rises with every frame.
    assert g.unsigned == 0
    stamps = [t for lid, t in g.sig]
    assert {lid for lid, t in g.sig} == {0}
    assert all(b2 > a for a, b2 in zip(stamps, stamps[1:]))
    assert stamps[-1] >= 5000  # caught up with the ground station's timestamp


def test_bad_replayed_and_unsigned_frames_dropped(tmp_path):
    b, svc = bench(tmp_path / "st")
    g = Gcs(b)
    setup_signing(g)
    seen = delivered(b)
    g.use_key(KEY, timestamp=10**9)
    f = g.send(g.mav.ping_encode(1, 1, 0, 0))
    g.run(2)
    assert seen == [4]
    # Replayed whole: same timestamp on the same stream.
    b.send_raw(f)
    g.run(2)
    assert svc.replayed == 1 and seen == [4]
    # Tampered signature, then tampered payload with the old signature.
    g.send(g.mav.ping_encode(2, 2, 0, 0))
    g.run(2)
    assert seen == [4, 4]
    bad = bytearray(g.mav.ping_encode(3, 3, 0, 0).pack(g.mav))
    bad[-1] ^= 0x40
    b.send_raw(bad)
    bad2 = bytearray(g.mav.ping_encode(4, 4, 0, 0).pack(g.mav))
    bad2[10] ^= 1  # payload byte; CRC fixed up so only the signature can tell
    crc = mav2.x25crc(bytes(bad2[1:10 + bad2[1]]))
    crc.accumulate(bytes([mav2.mavlink_map[4].crc_extra]))
    bad2[10 + bad2[1]] = crc.crc & 0xFF
    bad2[11 + bad2[1]] = crc.crc >> 8
    b.send_raw(bad2)
    g.run(2)
    assert svc.bad_signature == 2 and seen == [4, 4]
    # A key the vehicle does not have.
    other = Gcs(b, key=bytes(32 * [7]), link_id=1, timestamp=10**9)
    other.send(other.mav.ping_encode(5, 5, 0, 0))
    g.run(2)
    assert svc.bad_signature == 3 and seen == [4, 4]
    # Unsigned: PING and COMMAND_LONG dropped, HEARTBEAT accepted.
    plain = Gcs(b)
    plain.send(plain.mav.ping_encode(6, 6, 0, 0))
    plain.send(plain.mav.command_long_encode(1, 1, 520, 0, 1, 0, 0, 0, 0, 0, 0))
    plain.send(plain.mav.heartbeat_encode(6, 8, 0, 0, 0))
    g.run(2)
    assert svc.unsigned == 2 and seen == [4, 4, 0]
    # A new stream more than a minute behind our timestamp is a replay.
    old = Gcs(b, key=KEY, link_id=9, timestamp=10**9 - 6000001)
    old.send(old.mav.ping_encode(7, 7, 0, 0))
    g.run(2)
    assert svc.replayed == 2 and seen == [4, 4, 0]
    assert svc.accepted == 2


def test_setup_signing_rules(tmp_path):
    class Board:
        NAME = "bench"
        SIGNING_SETUP_LINKS = (1,)

    b, svc = bench(tmp_path / "a", board=Board)
    g = Gcs(b)
    setup_signing(g)
    assert not svc.enabled  # link 0 may not carry a key
    b, svc = bench(tmp_path / "b")
    g = Gcs(b)
    setup_signing(g, target=7)  # another vehicle's
    assert not svc.enabled
    setup_signing(g)
    assert svc.enabled
    # Now unsigned SETUP_SIGNING is dropped; a signed one with a zero key turns it off.
    plain = Gcs(b)
    setup_signing(plain, key=bytes(32))
    assert svc.enabled and svc.unsigned == 1
    g.out.clear()
    g.use_key(KEY, timestamp=svc.ts[0] | svc.ts[1] << 8 | svc.ts[2] << 16)
    setup_signing(g, key=bytes(32))
    assert not svc.enabled
    link = b.ep.links[0]
    assert link.rx.verify is None and link.tx.sign is None
    g.sig.clear()
    g.unsigned = 0
    g.run(1300)  # (the next HEARTBEAT: on status's second grid, up to 1125 ms away)
    assert g.unsigned > 0 and not g.sig


def test_timestamp_follows_time_of_day(tmp_path):
    b, svc = bench(tmp_path / "st")
    usec = 1767225600000000  # 2026-01-01
    b.ep.services["status"].set_clock(usec)
    g = Gcs(b)
    setup_signing(g)
    g.sig.clear()
    g.run(12000, step_ms=1)
    stamps = [t for lid, t in g.sig]
    expected = (usec - EPOCH_2015_US) // 10
    assert expected <= stamps[0] < expected + 130 * 1000  # the first HEARTBEAT: within 1125 ms (its grid)
    assert expected + 11 * 100000 <= stamps[-1] < expected + 13 * 100000
    assert all(b2 > a for a, b2 in zip(stamps, stamps[1:]))


def test_key_persists_across_restart_and_timestamp_moves_on(tmp_path):
    st = tmp_path / "st"
    b, svc = bench(st)
    g = Gcs(b)
    setup_signing(g, initial=123456789)
    g.run(50)
    last = max(t for lid, t in g.sig)
    assert last >= 123456789
    raw = (st / "signing_key").read_bytes()
    assert len(raw) == 42 and raw[:32] == KEY
    b2, svc2 = bench(st)
    assert svc2.enabled
    # A new stream must start above what the vehicle stored: a ground station going on
    # from the vehicle's last timestamp is refused until it has heard the vehicle, whose
    # timestamps go on from there.
    g2 = Gcs(b2, key=KEY, timestamp=last)
    g2.send(g2.mav.ping_encode(1, 1, 0, 0))
    g2.run(1100)
    msgs = g2.received()  # (pymavlink takes the vehicle's timestamp: it is ahead)
    assert "PING" not in {m.get_type() for m in msgs} and svc2.replayed == 1
    assert g2.mav.signing.badsig_count == 0 and g2.mav.signing.goodsig_count == len(msgs) > 0
    assert min(t for lid, t in g2.sig) > last
    g2.send(g2.mav.ping_encode(2, 2, 0, 0))
    g2.run(2)
    assert "PING" in {m.get_type() for m in g2.received()}


def stored(st):
    return int.from_bytes((st / "signing_key").read_bytes()[32:38], "little")


def test_stored_promise_floor_and_stop(tmp_path):
    """What is stored covers every timestamp accepted or sent (a frame ahead of it is
    stored before it goes on); after a restart a new stream must start above it; stop()
    stores the timestamp itself."""
    st = tmp_path / "st"
    b, svc = bench(st, board=type("B", (), {"NAME": "bench", "SIGNING_SAVE_MS": 5000}))
    g = Gcs(b)
    setup_signing(g, initial=10**9)
    ts = int.from_bytes(bytes(svc.ts), "little")
    assert 10**9 + 2 * 5000 * 100 <= stored(st) <= ts + 2 * 5000 * 100  # two save intervals ahead
    # A ground station ahead of the promise: stored before the frame is dispatched.
    seen = delivered(b)
    g.use_key(KEY, link_id=1, timestamp=ts + 3 * 5000 * 100)
    f = g.send(g.mav.ping_encode(1, 1, 0, 0))
    g.run(1)
    assert seen == [4] and stored(st) >= ts + 3 * 5000 * 100 + 5000 * 100
    promise = stored(st)
    # Power lost: after the restart, that frame (or anything at or below the promise) on a
    # new stream is refused; above it, accepted. Our timestamp goes on above it.
    b2, svc2 = bench(st)
    seen = delivered(b2)
    b2.send_raw(f)
    g2 = Gcs(b2, key=KEY, link_id=2, timestamp=promise)
    g2.send(g2.mav.ping_encode(2, 2, 0, 0))
    b2.run(2)
    assert seen == [] and svc2.replayed == 2
    g3 = Gcs(b2, key=KEY, link_id=3, timestamp=promise + 1)
    g3.send(g3.mav.ping_encode(3, 3, 0, 0))
    g3.run(2)
    assert seen == [4] and min(t for lid, t in g3.sig) > promise
    # A commanded reboot stores the timestamp itself: a station going on is in at once.
    g3.received()  # it has heard the vehicle up to its last frame
    svc2.stop()
    assert stored(st) == int.from_bytes(bytes(svc2.ts), "little")
    b3, svc3 = bench(st)
    seen = delivered(b3)
    g3.b = b3
    g3.send(g3.mav.ping_encode(4, 4, 0, 0))  # (pymavlink's next is the vehicle's last itself)
    g3.send(g3.mav.ping_encode(5, 5, 0, 0))
    b3.run(2)
    assert seen == [4] and svc3.replayed <= 1


def test_shutdown_stores_the_timestamp_before_the_board_powers_off(tmp_path):
    """A board's shutdown() may cut the power before main.py's last word: the timestamp
    itself is stored when the command is accepted, not the promise two intervals on."""
    from mavstack.endpoint import Shutdown

    st = tmp_path / "st"
    at_power_off = []

    class Board:
        NAME = "bench"

        @staticmethod
        def shutdown():
            at_power_off.append(stored(st))

    b = Bench(services=("signing", "status", "commands"), storage=str(st), board=Board)
    svc = b.ep.services["signing"]
    g = Gcs(b)
    setup_signing(g, initial=10**9)
    assert stored(st) >= 10**9 + 2 * 60000 * 100
    g.use_key(KEY, timestamp=int.from_bytes(bytes(svc.ts), "little") + 1)
    g.send(g.mav.command_long_encode(1, 1, 246, 0, 2, 0, 0, 0, 0, 0, 0))
    with pytest.raises(Shutdown):
        g.run(300)
    ts = int.from_bytes(bytes(svc.ts), "little")
    assert at_power_off and ts - 100 <= at_power_off[0] <= ts


def test_frames_far_ahead_refused_once_the_time_of_day_is_known(tmp_path):
    b, svc = bench(tmp_path / "st")
    g = Gcs(b)
    setup_signing(g)
    seen = delivered(b)
    # No time of day: the vehicle cannot tell a clock ahead from a right one (the spec's rule).
    early = Gcs(b, key=KEY, link_id=1, timestamp=5 * 10**9)
    early.send(early.mav.ping_encode(1, 1, 0, 0))
    b.run(2)
    assert seen == [4] and svc.future == 0
    usec = 1767225600000000  # 2026-01-01
    b2, svc2 = bench(tmp_path / "st2")
    b2.ep.services["status"].set_clock(usec)
    g = Gcs(b2)
    setup_signing(g)
    seen = delivered(b2)
    now = (usec - EPOCH_2015_US) // 10
    ahead = Gcs(b2, key=KEY, link_id=1, timestamp=now + 86400 * 100000)
    ahead.send(ahead.mav.ping_encode(1, 1, 0, 0))
    near = Gcs(b2, key=KEY, link_id=2, timestamp=now + 50 * 100000)  # 50 s ahead: taken
    near.send(near.mav.ping_encode(2, 2, 0, 0))
    b2.run(2)
    assert seen == [4] and svc2.future == 1
    ts = int.from_bytes(bytes(svc2.ts), "little")
    assert now + 50 * 100000 <= ts < now + 51 * 100000
    wall = Gcs(b2, key=KEY, link_id=3, timestamp=now + 100)  # from the wall clock: in
    wall.send(wall.mav.ping_encode(3, 3, 0, 0))
    b2.run(2)
    assert seen == [4, 4]


def test_corrupt_key_file_disables_signing_with_statustext(tmp_path):
    st = tmp_path / "st"
    b, svc = bench(st)
    setup_signing(Gcs(b))
    path = st / "signing_key"
    raw = bytearray(path.read_bytes())
    raw[5] ^= 0xFF
    path.write_bytes(bytes(raw))
    b2, svc2 = bench(st)
    assert not svc2.enabled
    g = Gcs(b2)
    g.run(1100)
    assert "Signing key corrupt: signing off" in texts(g.received())
    assert path.read_bytes() == bytes(raw)  # left for inspection, not overwritten
    assert b2.ep.links[0].rx.verify is None


def test_no_key_no_change_to_the_wire(tmp_path, monkeypatch):
    """Without a key the output is byte for byte what a vehicle without the service sends."""
    # Both benches start at one tick count: status's periods follow the start, then a grid of
    # the count, and the sequence numbers count what came before.
    monkeypatch.setattr(endpoint, "ticks_ms", lambda: 123456)
    outs = []
    for services in (("status",), ("signing", "status")):
        b = Bench(services=services, storage=str(tmp_path / ("s%d" % len(services))))
        g = Gcs(b)
        g.run(1500)
        g.send(g.mav.ping_encode(1, 1, 0, 0))
        g.run(2100)
        outs.append(bytes(g.out))
    assert outs[0] == outs[1] and len(outs[0]) > 100


# --- timestamps past 2^30, as pymavlink makes them ---------------------------------

def test_wall_clock_timestamps_from_pymavlink_on_two_links(tmp_path):
    """pymavlink's timestamps (10 us units since 2015 from the time of day, ~2^45) on two
    link ids: accepted in order, replays and a stream over a minute behind dropped, and
    the vehicle's own timestamps follow its time of day, past 2^32, rising per frame."""
    b, svc = bench(tmp_path / "st")
    usec = 1767225600000000  # 2026-01-01
    b.ep.services["status"].set_clock(usec)
    g = Gcs(b)
    setup_signing(g)
    seen = delivered(b)
    now = (usec - EPOCH_2015_US) // 10
    g.use_key(KEY, link_id=0, timestamp=now - 100000)  # a second behind the vehicle
    other = Gcs(b, key=KEY, link_id=1, timestamp=now + 500)  # a little ahead
    sent = []
    for i in range(10):
        sent.append(g.send(g.mav.ping_encode(i, i, 0, 0)))
        other.send(other.mav.ping_encode(100 + i, 100 + i, 0, 0))
        g.run(2)
    assert svc.accepted == 20 and seen.count(4) == 20
    # Ours moved past the ground station's that was ahead: max of both, then + 1 per frame.
    assert int.from_bytes(bytes(svc.ts), "little") >= now + 510
    b.send_raw(sent[3])
    b.send_raw(sent[9])
    stale = Gcs(b, key=KEY, link_id=2, timestamp=now - 6100000)
    stale.send(stale.mav.ping_encode(7, 7, 0, 0))
    g.run(2)
    assert svc.replayed == 3 and seen.count(4) == 20
    g.sig.clear()
    g.out.clear()
    g.run(3500)
    msgs = g.received()
    assert msgs and g.mav.signing.badsig_count == 0
    stamps = [t for lid, t in g.sig]
    assert stamps[0] > now + 510 and stamps[0] > 1 << 32
    assert all(b2 > a for a, b2 in zip(stamps, stamps[1:]))
    # The clock (time of day, advanced each second, re-read every 10 s) carries ours along.
    assert now + 2 * 100000 <= stamps[-1] < now + 4 * 100000


def test_timestamp_bytes_arithmetic_matches_ints():
    """The service's 48-bit byte helpers against Python ints."""
    from mavstack.services import signing

    rnd = random.Random(48)
    for _ in range(3000):
        a = rnd.choice([rnd.getrandbits(48), rnd.getrandbits(24),
                        (1 << 48) - 1 - rnd.getrandbits(8)])
        b2 = rnd.choice([a, a + rnd.randint(-3, 3), rnd.getrandbits(48),
                         a ^ (1 << rnd.randint(0, 47))]) % (1 << 48)
        ba = bytearray(a.to_bytes(6, "little"))
        bb = bytearray(bytes(3) + b2.to_bytes(6, "little"))
        assert signing._later(ba, 0, bb, 3) == (a > b2)
        n = rnd.randint(0, (1 << 29) - 1)
        out = bytearray(6)
        signing._plus(out, bb, 3, n)
        assert int.from_bytes(out, "little") == (b2 + n) % (1 << 48)
        ms = rnd.choice([0, 1, 999, 1000, 60000, rnd.randint(0, 10 ** 8)])
        signing._advance(ba, ms)
        assert int.from_bytes(ba, "little") == (a + ms * 100) % (1 << 48)
        usec = rnd.choice([0, 1, EPOCH_2015_US - 1, EPOCH_2015_US, EPOCH_2015_US + 9,
                           EPOCH_2015_US + rnd.getrandbits(50), rnd.getrandbits(64)])
        t = bytearray(usec.to_bytes(8, "little"))
        v = (usec - EPOCH_2015_US) // 10
        ok = signing._since_2015(t)
        assert ok == (0 <= v < 1 << 48)
        if ok:
            assert int.from_bytes(t[:6], "little") == v


# --- MicroPython: signed traffic under heap_lock ----------------------------------------

@pytest.mark.parametrize("portable", [False, True], ids=["mpy-viper", "mpy-portable"])
def test_signed_traffic_allocates_nothing(monkeypatch, portable):
    """signing_steady.py: wall-clock timestamps on two links, tampered, replayed, too old,
    a day ahead and unsigned frames, everything sent signed; the service's own paths (own=0) and the
    whole steady state (requested=0) ask the heap for nothing (harness.heap_requests),
    and N frames run under heap_lock."""
    if portable:
        monkeypatch.setenv("MAVSTACK_PORTABLE", "1")
    else:
        monkeypatch.delenv("MAVSTACK_PORTABLE", raising=False)
    n = 2000
    r = run_mpy(os.path.join(TESTS_MPY, "signing_steady.py"), n, "lock", path=[TESTS_MPY],
                timeout=120)
    assert r.returncode == 0, r.stderr
    line = r.stdout.strip().splitlines()[-1]
    words = line.split()
    f = dict(w.split("=", 1) for w in words[1:])
    assert words[0] == "ok", line
    assert f["impl"] == ("portable" if portable else "viper")
    k = n // 100
    # Verified; and dropped: tampered, replayed (an old frame, or a new stream too far
    # behind), unsigned.
    assert [int(f[x]) for x in ("accepted", "bad", "replayed", "unsigned", "future")] == [n, k, 2 * k, k, k]
    assert int(f["pings"]) == n  # every PING answered, signed
    assert int(f["out"]) >= n and f["bad_out"] == "0"
    assert f["own"] == "0" and f["locked"] == "ok" and f["saved"] == "1"
    # The whole steady state (parser, encoder, endpoint, status), storage_ram's save and
    # the copy kernel asked the heap for nothing either.
    assert (f["requested"], f["ram_save"], f["copy"]) == ("0", "0", "0"), line


# --- end to end: the unix vehicle with signing, restarted ---------------------------

SIGNED_BOARD = '''"""The unix vehicle with message signing (a test's board)."""
from unix import *  # noqa: F401,F403
import unix

NAME = "unix_signed"
SERVICES = ("signing",) + unix.SERVICES
'''
UNITS_PER_S = 100000  # signing timestamps: 10 us units


def wall_units():
    return int((time.time() - EPOCH_2015_US / 1e6) * UNITS_PER_S)


def signed_vehicle(vehicle, tmp_path, *args):
    """The unix vehicle (simulator, parameters, missions) with the signing service; its
    clock is the host's time of day."""
    from conftest import FIRMWARE

    boards = tmp_path / "boards"
    boards.mkdir(exist_ok=True)
    (boards / "unix_signed.py").write_text(SIGNED_BOARD)
    path = os.pathsep.join([str(boards), FIRMWARE, os.path.join(ROOT, "boards"), ".frozen"])
    return vehicle(board="unix_signed", env={"MICROPYPATH": path}, args=list(args))


def keyed(v, link_id, initial=None, port=None):
    """A ground station holding KEY, pymavlink's own way (its timestamps take the
    vehicle's when those are ahead)."""
    m = v.gcs(port=port)
    m.setup_signing(KEY, sign_outgoing=True, link_id=link_id, initial_timestamp=initial)
    return m


class WallClock:
    """A ground station that stamps from its wall clock (one up per frame when sent
    faster), whatever the vehicle's timestamps say."""

    def __init__(self, m):
        self.m = m
        self.next = 0

    def send(self, msg):
        s = self.m.mav.signing
        s.timestamp = max(wall_units(), self.next)
        self.m.mav.send(msg)
        self.next = s.timestamp

    def ask(self, msgid, timeout=3.0):
        """REQUEST_MESSAGE msgid, sent again each second -> the ACK's result or None."""
        deadline = time.time() + timeout
        while time.time() < deadline:
            self.send(self.m.mav.command_long_encode(1, 1, 512, 0, msgid, 0, 0, 0, 0, 0, 0))
            a = recv(self.m, "COMMAND_ACK", 1.0, lambda a: a.command == 512)
            if a is not None:
                return a.result
        return None


def switch_signing_on(m):
    m.mav.setup_signing_send(1, 1, KEY, wall_units())  # unsigned: the vehicle has no key yet
    m.setup_signing(KEY, sign_outgoing=True, link_id=0)
    assert recv(m, "STATUSTEXT", 5, lambda t: "Signing on" in t.text) is not None


def capture(m, msg):
    """Send msg signed and return its bytes: what someone listening on the link keeps."""
    buf = bytes(msg.pack(m.mav))
    m.mav.seq = (m.mav.seq + 1) & 0xFF
    m.write(buf)
    return buf


def read_param(m, name, timeout=10.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        m.mav.param_request_read_send(1, 1, name.encode(), -1)
        p = recv(m, "PARAM_VALUE", 0.5, lambda p: p.param_id == name)
        if p is not None:
            return p.param_value
    return None


def armed(m, seconds=1.5):
    """Any vehicle HEARTBEAT armed within seconds?"""
    deadline = time.time() + seconds
    seen = False
    while time.time() < deadline:
        hb = recv(m, "HEARTBEAT", 0.3, lambda h: h.get_srcSystem() == 1)
        seen = seen or (hb is not None and bool(hb.base_mode & 128))
    return seen


def captured_arm_and_param_set(m):
    """A signed ARM and PARAM_SET SIM_SPEED=9 that the vehicle carried out (then undone,
    and the parameters saved), as an eavesdropper would have kept them."""
    arm = capture(m, m.mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 400).result == 0
    param = capture(m, m.mav.param_set_encode(1, 1, b"SIM_SPEED", 9.0, 9))
    assert recv(m, "PARAM_VALUE", 5, lambda p: p.param_id == "SIM_SPEED" and p.param_value == 9.0)
    m.mav.command_long_send(1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 400).result == 0
    m.mav.param_set_send(1, 1, b"SIM_SPEED", 5.0, 9)
    assert recv(m, "PARAM_VALUE", 5, lambda p: p.param_id == "SIM_SPEED" and p.param_value == 5.0)
    m.mav.command_long_send(1, 1, 245, 0, 1, 0, 0, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 245).result == 0
    return arm, param


def replayed_took_effect(watcher, frames):
    """Replay frames from an eavesdropper's socket -> what each did: (armed, SIM_SPEED 9)."""
    while watcher.recv_match(blocking=False) is not None:
        pass  # what it heard before (the vehicle writes to every UDP peer)
    for f in frames:
        watcher.write(f)
    nine = recv(watcher, "PARAM_VALUE", 1.5, lambda p: p.param_id == "SIM_SPEED" and p.param_value == 9.0)
    return armed(watcher), nine is not None


def test_frames_captured_before_a_restart_are_refused_after_it(vehicle, tmp_path):
    """A signed ARM and PARAM_SET kept by an eavesdropper and replayed after the vehicle
    restarts, from power loss (kill -9) and from a commanded reboot: refused, 4 of 4; the
    ground station that holds the key goes on."""
    v = signed_vehicle(vehicle, tmp_path)
    m = v.gcs()
    switch_signing_on(m)
    frames = captured_arm_and_param_set(m)
    v.kill()  # power lost, a few seconds after the key was saved
    v = signed_vehicle(vehicle, tmp_path)
    watcher = v.gcs(source_system=250)  # unsigned heartbeats: let through, change nothing
    assert replayed_took_effect(watcher, frames) == (False, False)
    m = keyed(v, link_id=1)
    assert read_param(m, "SIM_SPEED") == 5.0
    frames = captured_arm_and_param_set(m)
    m.mav.command_long_send(1, 1, 246, 0, 1, 0, 0, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 246).result == 0
    assert recv(m, "STATUSTEXT", 5, lambda t: "Rebooting" in t.text) is not None
    time.sleep(1.5)  # restarted in place
    assert replayed_took_effect(watcher, frames) == (False, False)
    assert read_param(m, "SIM_SPEED") == 5.0
    assert v.proc.poll() is None


def test_future_stamped_frame_does_not_lock_out_a_wall_clock_gcs(vehicle, tmp_path):
    """A key holder whose clock is a day ahead is refused by a vehicle that knows the time
    of day; a ground station stamping from the wall clock keeps working, before and after
    a commanded reboot."""
    v = signed_vehicle(vehicle, tmp_path)
    m = v.gcs()
    switch_signing_on(m)
    time.sleep(1.5)  # the vehicle's signing clock has taken the time of day
    ahead = keyed(v, link_id=7, initial=wall_units() + 86400 * UNITS_PER_S)
    ahead.mav.command_long_send(1, 1, 512, 0, 2, 0, 0, 0, 0, 0, 0)
    ahead.mav.command_long_send(1, 1, 512, 0, 2, 0, 0, 0, 0, 0, 0)
    assert recv(ahead, "COMMAND_ACK", 1.5, lambda a: a.command == 512) is None
    gcs = WallClock(keyed(v, link_id=8))
    assert gcs.ask(2) == 0
    assert WallClock(keyed(v, link_id=9)).ask(2) == 0  # a new stream, from the wall clock
    # m has not read for 5 s of streams: its socket's buffer may be full, and a full one
    # drops the ACK (the kernel's RcvbufErrors). A ground station reads as it goes.
    while m.recv_match(blocking=False) is not None:
        pass
    m.mav.command_long_send(1, 1, 246, 0, 1, 0, 0, 0, 0, 0, 0)
    assert recv(m, "COMMAND_ACK", 5, lambda a: a.command == 246).result == 0
    time.sleep(1.5)
    assert WallClock(keyed(v, link_id=10)).ask(2, timeout=5) == 0
    assert gcs.ask(2) == 0
