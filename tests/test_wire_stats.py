"""Per-link receive statistics: frames, CRC errors, bytes discarded, and frames lost to
sequence gaps per source (sources interleaved, sequence numbers wrapping)."""
import random

import pytest

from mavstack.endpoint import Endpoint
from mavstack.parser import Parser
from wire_oracle import OURS, MemoryTransport, parse_files, reference

M2 = reference("common", 2)
COMMON = OURS["common"]


def hb(seq, sysid, compid, version=2):
    m = M2.MAVLink(None, sysid, compid)
    m.seq = seq & 0xFF
    return M2.MAVLink_heartbeat_message(2, 3, 81, seq, 4, 3).pack(m, force_mavlink1=version == 1)


def bad_crc(f):
    b = bytearray(f)
    b[-1] ^= 0xFF
    return bytes(b)


def two_sources(seed):
    """Two senders interleaved, each with gaps and a sequence wrap; noise and a damaged
    frame in between. -> (stream, expected statistics)."""
    rnd = random.Random(seed)
    a = [(s, 1, 1) for s in range(200, 200 + 150) if s % 17 != 5]  # 200..349 wraps past 255
    b = [(s, 1, 2) for s in range(0, 120) if s not in (10, 11, 12, 90)]
    lost = (150 - len(a)) + 4
    frames = len(a) + len(b) - 1  # all but the damaged one
    stream, damaged, noise = bytearray(), None, 0
    while a or b:
        src = a if (a and (not b or rnd.random() < 0.55)) else b
        seq, sysid, compid = src.pop(0)
        f = hb(seq, sysid, compid, version=rnd.choice([1, 2]))
        if damaged is None and seq == 60 and compid == 2:
            damaged = f = bad_crc(f)  # arrives damaged: a CRC error and one frame lost
            lost += 1
        stream += f
        if rnd.random() < 0.1:
            junk = bytes(rnd.randrange(0xFD) for _ in range(rnd.randint(1, 20)))
            stream += junk
            noise += len(junk)
    return bytes(stream), dict(frames=frames, crc_errors=1,
                               bytes_discarded=noise + len(damaged), lost=lost)


def test_two_sources_two_links():
    ep = Endpoint(COMMON, sysid=1, compid=1)
    ta, tb = MemoryTransport(), MemoryTransport()
    la, lb = ep.add_link(ta), ep.add_link(tb)
    sa, want_a = two_sources(1)
    sb, want_b = two_sources(2)
    ta.rx += sa
    tb.rx += sb[:len(sb) // 2]
    while ta.rx or tb.rx:
        ep.poll(0)
    tb.rx += sb[len(sb) // 2:]
    while tb.rx:
        ep.poll(0)
    for link, want in ((la, want_a), (lb, want_b)):
        got = {k: getattr(link.rx, k) for k in want}
        assert got == want
        assert link.rx.unknown_ids == link.rx.bad_frames == 0
    la.rx.reset_stats()
    assert la.rx.frames == la.rx.lost == la.rx.crc_errors == la.rx.bytes_discarded == 0
    assert lb.rx.frames == want_b["frames"]


@pytest.mark.parametrize("portable", [False, True], ids=["viper", "portable"])
def test_two_sources_micropython(tmp_path, portable):
    stream, want = two_sources(3)
    path = tmp_path / "two.bin"
    path.write_bytes(stream)
    [(frames, stats)], _ = parse_files("common", [path], "r6", tmp_path / "out.txt", "mpy", portable)
    assert {k: stats[k] for k in want} == want


def test_many_sources_and_wraps_count_no_false_losses():
    """More senders than the table tracks, each in sequence: nothing is counted lost."""
    ep = Endpoint(COMMON)
    t = MemoryTransport()
    link = ep.add_link(t)
    for i in range(600):
        for src in range(12):
            t.rx += hb(i, 10 + src, 1)
        ep.poll(0)
    assert link.rx.frames == 600 * 12 and link.rx.lost == 0


def test_gap_sizes():
    ep = Endpoint(COMMON)
    t = MemoryTransport()
    link = ep.add_link(t)
    for seq in (5, 6, 9, 190, 255, 0, 1, 100):  # gaps: 2, 180, 64, 0, 0, 98
        t.rx += hb(seq, 1, 1)
    ep.poll(0)
    assert link.rx.frames == 8 and link.rx.lost == 2 + 180 + 64 + 98


def test_late_frames_are_marked_not_counted_lost():
    """A frame numbered up to 64 before the newest one from its sender (held back by the
    link) is delivered and marked late (late_at == frames while it is handled); it
    counts no loss and leaves the sender's newest number. A repeated number (a duplicate,
    or a sender that numbers nothing) is neither late nor a loss."""
    ep = Endpoint(COMMON)
    t = MemoryTransport()
    link = ep.add_link(t)
    seen = []
    ep.on(0, lambda lk, p: seen.append((lk.rx.seq, lk.rx.late_at == lk.rx.frames)))
    for seq in (10, 11, 12, 13, 11, 14, 14, 200, 201, 150, 202, 203):
        t.rx += hb(seq, 1, 1)
    t.rx += hb(7, 1, 2)  # another sender: its own numbers
    while t.rx:
        ep.poll(0)
    assert seen == [(10, False), (11, False), (12, False), (13, False), (11, True), (14, False), (14, False),
                    (200, False), (201, False), (150, True), (202, False), (203, False), (7, False)]
    assert link.rx.lost == 185  # 14 -> 200 only


def test_verify_hook_set_by_a_frame_applies_to_the_next_in_the_same_chunk():
    """Frames that arrive whole inside one chunk are delivered one at a time: a verify
    hook that a handler sets (as SETUP_SIGNING's does) judges the very next frame, sees
    it as on the wire (a trimmed payload's CRC still in place), and what it drops is
    neither delivered nor counted, in frames or in sequence losses."""
    got, seen = [], []
    p = None

    def verify(buf, plen, signed):
        wire = buf[10 + plen] | buf[11 + plen] << 8
        seen.append((buf[4], plen, wire))
        return buf[4] % 2 == 0  # even sequence numbers pass

    def on_frame(msgid, payload):
        got.append(p.seq)
        if p.seq == 1:
            p.verify = verify

    def attitude(seq):  # its payload's trailing zeros trimmed on the wire
        m = M2.MAVLink(None, 1, 1)
        m.seq = seq
        return M2.MAVLink_attitude_message(seq, 0.5, 0.25, 0.0, 0.0, 0.0, 0.0).pack(m)

    p = Parser(COMMON.CRC_LEN, on_frame)
    frames = [hb(seq, 1, 1) if seq % 3 else attitude(seq) for seq in range(6)]
    assert frames[3][1] < 28
    data = bytearray(b"".join(frames))
    p.feed(data, len(data))
    assert got == [0, 1, 2, 4]
    for (seq, plen, wire), f in zip(seen, frames[2:]):
        assert seq == f[4] and plen == f[1] and wire == f[-2] | f[-1] << 8
    assert p.frames == 4 and p.lost == 1  # 3 was dropped: 2 -> 4 is a gap of one
    p.verify = None
    more = bytearray(hb(5, 1, 1) + hb(6, 1, 1))
    p.feed(more, len(more))
    assert got[-2:] == [5, 6] and p.frames == 6


def test_counters_wrap_below_2_30():
    """On a 32-bit board an int of 2^30 or more is a heap object: the counters wrap at
    2^29 (COUNT_WRAP), and differences taken modulo that are the counts. (The emulated
    boards run the wire path under heap_lock from just below the wrap: test_mcu.py.)"""
    from mavstack.parser import COUNT_WRAP

    stream, want = two_sources(4)
    ep = Endpoint(COMMON)
    t = MemoryTransport()
    link = ep.add_link(t)
    start = COUNT_WRAP - 3
    for name in want:
        setattr(link.rx, name, start)
    link.tx.frames = start
    t.rx += stream
    while t.rx:
        ep.poll(0)
    for name in want:
        value = getattr(link.rx, name)
        assert 0 <= value <= COUNT_WRAP and (value < start or want[name] < 3), name  # wrapped
        assert (value - start) & COUNT_WRAP == want[name], name
    for _ in range(5):
        link.tx.begin()
        link.send(0)  # HEARTBEAT's payload of zeros
    assert link.tx.frames == 1
