"""MAVLink 2 signing: the SHA-256 kernels (viper, portable) against hashlib on every runtime, the signing
service in-process with pymavlink (with its secret key) as the ground station and
oracle, key persistence, and signed traffic under heap_lock() on MicroPython."""
import hashlib
import os
import random
import sys

import pytest

from conftest import ROOT, run_mpy

TESTS_MPY = os.path.join(ROOT, "tests", "mpy")
if TESTS_MPY not in sys.path:
    sys.path.insert(0, TESTS_MPY)

from harness import Bench  # noqa: E402
from pymavlink.dialects.v20 import common as mav2  # noqa: E402

from mavstack.parser import Parser  # noqa: E402
from mavstack.services.sha256 import Sha256  # noqa: E402

KEY = bytes(range(1, 33))
EPOCH_2015_US = 1420070400000000

SHA_SCRIPT = """
import sys
from binascii import hexlify, unhexlify
from mavstack.services.sha256 import Sha256, SHA256_IMPL
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
    g.run(1100)
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
    assert expected <= stamps[0] < expected + 100 * 1000
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
    # A new stream must be no more than a minute behind the vehicle's timestamp.
    g2 = Gcs(b2, key=KEY, timestamp=last)
    g2.send(g2.mav.ping_encode(1, 1, 0, 0))
    g2.run(1100)
    msgs = g2.received()
    assert "PING" in {m.get_type() for m in msgs}
    assert g2.mav.signing.badsig_count == 0 and g2.mav.signing.goodsig_count == len(msgs)
    assert min(t for lid, t in g2.sig) > last


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


def test_no_key_no_change_to_the_wire(tmp_path):
    """Without a key the output is byte for byte what a vehicle without the service sends."""
    outs = []
    for services in (("status",), ("signing", "status")):
        b = Bench(services=services, storage=str(tmp_path / ("s%d" % len(services))))
        g = Gcs(b)
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
    """signing_steady.py: wall-clock timestamps on two links, tampered, replayed, too old
    and unsigned frames, everything sent signed; the service's own paths (own=0) and the
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
    assert [int(f[x]) for x in ("accepted", "bad", "replayed", "unsigned")] == [n, k, 2 * k, k]
    assert int(f["pings"]) == n  # every PING answered, signed
    assert int(f["out"]) >= n and f["bad_out"] == "0"
    assert f["own"] == "0" and f["locked"] == "ok" and f["saved"] == "1"
    # The whole steady state (parser, encoder, endpoint, status), storage_ram's save and
    # the copy kernel asked the heap for nothing either.
    assert (f["requested"], f["ram_save"], f["copy"]) == ("0", "0", "0"), line
