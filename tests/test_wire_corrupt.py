"""Damaged input: every intact frame is delivered exactly once and nothing else is, on both
runtimes and kernel sets; resynchronisation cases built by hand; any bytes at all never
raise and leave the statistics consistent."""
import random
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavstack.parser import Parser
from wire_oracle import (OURS, RUNTIME_IDS, RUNTIMES, corrupt, crc_extra, frame, full_len,
                         parse_files, random_frames, reference, strip_crc, x25)
import wire_tool

CRC_LEN = OURS["common"].CRC_LEN
M2 = reference("common", 2)
# Enough trailing bytes for a candidate still open at the end of the stream to be
# rejected, so that frames it swallowed are found.
TAIL = bytes(2000)


def hb(seq=0, version=2, sysid=1, compid=1, custom_mode=7):
    m = M2.MAVLink(None, sysid, compid)
    m.seq = seq
    return M2.MAVLink_heartbeat_message(2, 3, 81, custom_mode, 4, 3).pack(m, force_mavlink1=version == 1)


def attitude(seq=0, roll=0.5):
    m = M2.MAVLink(None, 1, 1)
    m.seq = seq
    return M2.MAVLink_attitude_message(1000 + seq, roll, -0.25, 3.0, 0.125, 0.5, -1.0).pack(m)


def encapsulated(inner, seq=0):
    """ENCAPSULATED_DATA (full length 255) carrying `inner` in its payload."""
    m = M2.MAVLink(None, 1, 1)
    m.seq = seq
    data = list(inner) + [0x55] * (253 - len(inner))
    return M2.MAVLink_encapsulated_data_message(7, data).pack(m)


def with_bad_crc(f):
    hdr = 10 if f[0] == 0xFD else 6
    b = bytearray(f)
    b[hdr + f[1]] ^= 0x5A
    return bytes(b)


def collect(data, chunk=0):
    """Parse on CPython -> (delivered [(header+payload, signature)], parser, records)."""
    got, records = [], []

    def on_frame(msgid, payload):
        buf = p.buf
        hdr = 10 if p.version == 2 else 6
        got.append((bytes(buf[:hdr + buf[1]]), bytes(p.signature) if p.signed else b""))
        records.append((p.version, msgid, p.seq, p.sysid, p.compid,
                        bytes(payload[:full_len("common", msgid)])))

    p = Parser(CRC_LEN, on_frame)
    if chunk:
        for i in range(0, len(data), chunk):
            p.feed(data[i:i + chunk])
    else:
        p.feed(data)
    return got, p, records


def accounted(data, got, p):
    """Every byte fed is in a delivered frame, discarded, or still held by the parser."""
    delivered = sum(len(w) + 2 + len(s) for w, s in got)
    return delivered + p.bytes_discarded + wire_tool.pending(p) == len(data)


# --- long damaged streams ------------------------------------------------------------


@pytest.mark.parametrize("runtime,portable", RUNTIMES, ids=RUNTIME_IDS)
def test_damaged_stream_intact_frames_delivered_once(tmp_path, runtime, portable):
    # Seeded so that no damaged frame happens to pass the 16-bit CRC (about one in
    # 65536 damaged frames would, and would then rightly be delivered).
    rnd = random.Random(4242)
    frames = random_frames(rnd, 4000, v1_share=0.35, signed_share=0.25)
    stream, intact = corrupt(rnd, frames, rate=0.15, garbage_rate=0.15)
    stream += TAIL
    path = tmp_path / "damaged.bin"
    path.write_bytes(stream)
    chunks = {"mpy-viper": "r1", "mpy-portable": "r2", "cpython": "r3"}[
        RUNTIME_IDS[RUNTIMES.index((runtime, portable))]]
    [(got, stats)], impl = parse_files("common", [path], chunks, tmp_path / "out.txt", runtime, portable)
    assert impl == ("portable" if portable else "viper")
    delivered = [(f["wire"], f["signature"]) for f in got]
    expect = [strip_crc(frames[i]) for i in intact]
    assert len(expect) > 3000 and any(s for _, s in expect)
    assert delivered == expect
    assert stats["frames"] == len(expect)
    assert stats["crc_errors"] > 0 and stats["bad_frames"] > 0 and stats["unknown_ids"] > 0
    wire = sum(len(f["wire"]) + 2 + len(f["signature"]) for f in got)
    assert wire + stats["bytes_discarded"] + stats["pending"] == len(stream)


@pytest.mark.parametrize("chunk", [1, 2, 3, 7, 10, 64, 255, 281, 1024, 4096])
def test_chunk_size_does_not_matter(chunk):
    rnd = random.Random(chunk)
    frames = random_frames(rnd, 300, v1_share=0.4, signed_share=0.3)
    stream, intact = corrupt(rnd, frames, rate=0.2, garbage_rate=0.2)
    stream += TAIL
    whole, pw, rec_whole = collect(stream)
    got, p, rec = collect(stream, chunk)
    assert got == whole == [strip_crc(frames[i]) for i in intact]
    assert rec == rec_whole
    for k in wire_tool.STATS:
        assert getattr(p, k) == getattr(pw, k), k
    assert accounted(stream, got, p)


# --- resynchronisation cases, by hand --------------------------------------------------


def _cases():
    cases = {}
    a, b, c = hb(1), attitude(2), hb(3, version=1)
    # Noise without start markers is discarded byte for byte.
    noise = bytes(i % 0xFD for i in range(50))
    cases["noise"] = (noise + a, [a], dict(bytes_discarded=50))
    # Bare start markers and a marker inside a frame's own header.
    cases["stray_markers"] = (b"\xfd\xfe\xfd" + a + b"\xfe" + b, [a, b], dict(frames=2))
    # A fake MAVLink 2 header whose length swallows the next real frames.
    fake = bytes([0xFD, 200, 0, 0, 9, 1, 1, 131, 0, 0])
    cases["fake_v2_header"] = (fake + a + b + c + hb(4) * 10, [a, b, c] + [hb(4)] * 10,
                               dict(crc_errors=1))
    # A fake MAVLink 1 header (HEARTBEAT length) swallowing the start of a real frame.
    fake1 = bytes([0xFE, 9, 0, 1, 1, 0])
    cases["fake_v1_header"] = (fake1 + b + a, [b, a], dict(crc_errors=1))
    # A damaged frame followed by a good one.
    cases["bad_crc"] = (with_bad_crc(a) + b, [b], dict(crc_errors=1, frames=1))
    # A valid frame carried inside a frame that fails its CRC is found...
    outer = encapsulated(c)
    cases["frame_inside_rejected"] = (with_bad_crc(outer) + a, [c, a], dict(crc_errors=1))
    # ... but not inside one that passes: it is payload there.
    cases["frame_inside_valid"] = (outer + a, [outer, a], dict(frames=2, crc_errors=0))
    # Ids this dialect does not know are counted and skipped.
    unknown2 = frame(2, 0xABCDE, b"\x01\x02\x03", 0)
    unknown1 = frame(1, 3, b"\x01" * 9, 0)
    cases["unknown_ids"] = (unknown2 + a + unknown1 + b, [a, b], dict(unknown_ids=2, frames=2))
    # Incompatibility flags we do not understand: the frame is dropped.
    p = a[10:10 + a[1]]
    flagged = frame(2, 0, p, crc_extra("common", 0), iflags=0x02)
    cases["unknown_incompat_flag"] = (flagged + b, [b], dict(bad_frames=1, frames=1))
    # Lengths a message cannot have: beyond the full length (v2), other than the base
    # length (v1), or zero (v2 keeps at least one byte).
    too_long = frame(2, 0, bytes(range(1, 11)), crc_extra("common", 0))
    wrong_v1 = frame(1, 0, bytes(range(1, 11)), crc_extra("common", 0))
    empty = frame(2, 0, b"", crc_extra("common", 0))
    cases["impossible_lengths"] = (too_long + wrong_v1 + empty + a, [a], dict(bad_frames=3, frames=1))
    # Signed frames pass without verification, signature kept.
    sig = bytes(range(100, 113))
    signed = frame(2, 0, p, crc_extra("common", 0), signature=sig)
    cases["signed"] = (signed + a, [signed, a], dict(frames=2))
    # A truncated payload after a long one: the tail reads as zeros, not as stale bytes.
    short = frame(2, 30, b"\x09", crc_extra("common", 30))
    cases["truncated"] = (b + short, [b, short], dict(frames=2))
    return cases


CASES = _cases()


def _check_case(name, got, stats):
    stream, expect, want = CASES[name]
    assert got == [strip_crc(f) for f in expect], name
    for k, v in want.items():
        assert stats[k] == v, (name, k, stats)


@pytest.mark.parametrize("name", sorted(CASES))
def test_resync_case_cpython(name):
    stream, expect, want = CASES[name]
    got, p, records = collect(stream)
    _check_case(name, got, {k: getattr(p, k) for k in wire_tool.STATS})
    assert accounted(stream, got, p)
    if name == "truncated":
        assert records[1][5] == b"\x09" + bytes(27)
    for chunk in (1, 3, 11):
        assert collect(stream, chunk)[0] == got


@pytest.mark.parametrize("portable", [False, True], ids=["viper", "portable"])
def test_resync_cases_micropython(tmp_path, portable):
    names = sorted(CASES)
    paths = []
    for name in names:
        path = tmp_path / (name + ".bin")
        path.write_bytes(CASES[name][0])
        paths.append(path)
    for chunks in ("1", "r4"):
        results, _ = parse_files("common", paths, chunks, tmp_path / "out.txt", "mpy", portable)
        for name, (frames, stats) in zip(names, results):
            _check_case(name, [(f["wire"], f["signature"]) for f in frames], stats)
        truncated = results[names.index("truncated")][0][1]
        assert truncated["payload"] == b"\x09" + bytes(27)


# --- any bytes at all ----------------------------------------------------------------


def check_delivered_valid(data, got, p, records):
    assert accounted(data, got, p)
    assert p.frames == len(got)
    for (wire, sig), rec in zip(got, records):
        msgid = rec[1]
        assert msgid in CRC_LEN
        hdr = 10 if wire[0] == 0xFD else 6
        # Only frames whose CRC holds are delivered: find it in the input.
        crc = x25(wire[1:], crc_extra("common", msgid))
        assert wire + struct.pack("<H", crc) + sig in data
        assert 0 < wire[1] <= full_len("common", msgid)
        assert rec[5][wire[1]:] == bytes(full_len("common", msgid) - wire[1])
        assert rec[5][:wire[1]] == wire[hdr:]


FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SOME_FRAMES = [hb(1), attitude(2), hb(3, version=1), encapsulated(hb(4)),
               frame(2, 0, b"\x01", crc_extra("common", 0), signature=bytes(13))]


@FUZZ
@given(st.binary(max_size=3000), st.integers(1, 600))
def test_random_bytes_never_raise(data, chunk):
    got, p, records = collect(data, chunk)
    check_delivered_valid(data, got, p, records)


@FUZZ
@given(st.lists(st.one_of(st.sampled_from(SOME_FRAMES), st.binary(max_size=40),
                          st.sampled_from([b"\xfd", b"\xfe", b"\xfd\xff", b"\xfe\x09"])),
                max_size=30),
       st.lists(st.tuples(st.integers(0, 10000), st.integers(0, 255)), max_size=8),
       st.integers(1, 300))
def test_mutated_frames_never_raise(parts, flips, chunk):
    data = bytearray(b"".join(parts))
    for at, x in flips:
        if data:
            data[at % len(data)] ^= x
    data = bytes(data)
    got, p, records = collect(data, chunk)
    check_delivered_valid(data, got, p, records)
    assert (got, records) == collect(data)[::2]


@pytest.mark.parametrize("runtime,portable", RUNTIMES[:2], ids=RUNTIME_IDS[:2])
def test_micropython_random_bytes_never_raise(tmp_path, runtime, portable):
    """Half a megabyte of noise, markers and frame fragments: no exception (the tool
    would exit non-zero), and the same result as CPython's."""
    rnd = random.Random(99)
    out = bytearray()
    frames = random_frames(rnd, 300)
    while len(out) < 500000:
        r = rnd.random()
        if r < 0.3:
            out += rnd.randbytes(rnd.randint(1, 300))
        elif r < 0.6:
            out += bytes(rnd.choice([0xFD, 0xFE, 0, 255, 9, 1]) for _ in range(rnd.randint(1, 30)))
        else:
            f = rnd.choice(frames)
            a = rnd.randrange(len(f))
            out += f[a:] if rnd.random() < 0.5 else f[:a]
    path = tmp_path / "noise.bin"
    path.write_bytes(bytes(out))
    [(got, stats)], _ = parse_files("common", [path], "r8", tmp_path / "mpy.txt", runtime, portable)
    [(ref, ref_stats)], _ = parse_files("common", [path], "4096", tmp_path / "cpy.txt", "cpython")
    assert got == ref and stats == ref_stats
    assert stats["frames"] > 0
