"""Every message of both dialects, MAVLink 1 and 2, with random field values (NaN, +-inf,
integer extremes, full-length strings and arrays, zero tails that MAVLink 2 trims):
frames pymavlink encodes parse to the same fields, and frames we encode (FMT pack_into,
Encoder.finish) are pymavlink's own bytes and decode in pymavlink to the same values.
CPython in-process (seeded sweep plus hypothesis), MicroPython in batches."""
import random
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavstack.encoder import Encoder
from mavstack.parser import Parser
from wire_oracle import (OURS, classes, decode_frames, fields, flat, full_len,
                         has_nan, pack, random_values, run_tool, same, values_strategy,
                         read_parsed)

CASES = [("common", 2), ("common", 1), ("seed2012", 2), ("seed2012", 1)]
CASE_IDS = ["common-v2", "common-v1", "seed2012-v2", "seed2012-v1"]
SIGN_KEY = bytes(range(32))


def full_payload(frame, dialect, msgid):
    hdr = 10 if frame[0] == 0xFD else 6
    payload = frame[hdr:hdr + frame[1]]
    return payload + bytes(full_len(dialect, msgid) - len(payload))


def full_values(dialect, cls, values):
    """Arguments for pack_into(FMT): the message's values, then zeros for the MAVLink 2
    extension fields a MAVLink 1 class does not have."""
    fmt = OURS[dialect].FMT[cls.id]
    vals = flat(cls, values)
    zeros = struct.unpack(fmt, bytes(struct.calcsize(fmt)))
    return vals + list(zeros[len(vals):])


def parse(dialect, data):
    got = []

    def on_frame(msgid, payload):
        got.append(dict(version=p.version, msgid=msgid, seq=p.seq, sysid=p.sysid,
                        compid=p.compid, signed=p.signed, signature=bytes(p.signature),
                        payload=bytes(payload[:full_len(dialect, msgid)])))

    p = Parser(OURS[dialect].CRC_LEN, on_frame)
    p.feed(data)
    return got, p


def check_parse(dialect, version, cls, values, seq, sysid, compid, signed=False):
    frame = pack(dialect, version, cls, values, seq, sysid, compid, SIGN_KEY if signed else None)
    crc_len = OURS[dialect].CRC_LEN[cls.id]
    if version == 1:
        assert frame[1] == (crc_len >> 8) & 0xFF  # MAVLink 1 carries the base fields only
    got, p = parse(dialect, frame)
    assert len(got) == 1 and p.frames == 1, (cls.msgname, frame.hex())
    assert p.crc_errors == p.bytes_discarded == p.unknown_ids == p.bad_frames == 0
    f = got[0]
    assert (f["version"], f["msgid"], f["seq"], f["sysid"], f["compid"], f["signed"]) == (
        version, cls.id, seq, sysid, compid, signed)
    if signed:
        assert f["signature"] == frame[-13:]
    # Raw bytes: pymavlink's payload, zero-extended to the full length.
    assert f["payload"] == full_payload(frame, dialect, cls.id)
    # Values: unpacked with our FMT, as the stack reads them.
    fmt = OURS[dialect].FMT[cls.id]
    assert struct.calcsize(fmt) == full_len(dialect, cls.id)
    unpacked = struct.unpack(fmt, f["payload"])
    expect = full_values(dialect, cls, values)
    assert same(list(unpacked), expect), cls.msgname


def check_encode(dialect, version, cls, values, seq, sysid, compid):
    frame = pack(dialect, version, cls, values, seq, sysid, compid)
    enc = Encoder(OURS[dialect].CRC_LEN, version)
    enc.seq = seq
    off = enc.begin()
    struct.pack_into(OURS[dialect].FMT[cls.id], enc.buf, off,
                     *full_values(dialect, cls, values))
    n = enc.finish(cls.id, sysid, compid)
    ours = bytes(enc.buf[:n])
    assert ours == frame, cls.msgname
    assert enc.seq == (seq + 1) & 0xFF
    check_decoded(dialect, version, ours, cls, values, seq, sysid, compid)


def check_decoded(dialect, version, data, cls, values, seq, sysid, compid):
    msgs = decode_frames(dialect, version, data)
    assert len(msgs) == 1, msgs
    m = msgs[0]
    assert m.get_type() == cls.msgname, (m, data.hex())
    assert (m.get_seq(), m.get_srcSystem(), m.get_srcComponent()) == (seq, sysid, compid)
    for name, t, n in fields(cls):
        got = getattr(m, "_%s_raw" % name) if t == "char" else getattr(m, name)
        assert same(got, values[name]), (cls.msgname, name, got, values[name])


# --- CPython: every message, seeded ---------------------------------------------------


@pytest.mark.parametrize("dialect,version", CASES, ids=CASE_IDS)
def test_every_message_both_directions(dialect, version):
    rnd = random.Random("%s-%d" % (dialect, version))
    msgs = classes(dialect, version)
    assert len(msgs) == len([i for i in OURS[dialect].CRC_LEN if version == 2 or i < 256])
    for rounds in range(4):
        for cls in msgs:
            values = random_values(cls, rnd)
            head = rnd.getrandbits(8), rnd.getrandbits(8), rnd.getrandbits(8)
            signed = version == 2 and rounds == 3
            check_parse(dialect, version, cls, values, *head, signed=signed)
            check_encode(dialect, version, cls, values, *head)


# --- CPython: hypothesis --------------------------------------------------------------

_strategies = {}


def message_batches(dialect, version):
    msgs = classes(dialect, version)
    for cls in msgs:
        _strategies.setdefault((dialect, version, cls.id), values_strategy(cls))
    one = st.sampled_from(msgs).flatmap(
        lambda cls: st.tuples(st.just(cls), _strategies[dialect, version, cls.id],
                              st.integers(0, 255), st.integers(0, 255), st.integers(0, 255)))
    return st.lists(one, min_size=1, max_size=3)


HYP = settings(max_examples=60, deadline=None,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _hypothesis_case(dialect, version):
    @HYP
    @given(batch=message_batches(dialect, version))
    def run(batch):
        for cls, values, seq, sysid, compid in batch:
            check_parse(dialect, version, cls, values, seq, sysid, compid)
            check_encode(dialect, version, cls, values, seq, sysid, compid)
    return run


@pytest.mark.parametrize("dialect,version", CASES, ids=CASE_IDS)
def test_hypothesis_messages_both_directions(dialect, version):
    _hypothesis_case(dialect, version)()


@HYP
@given(data=st.binary(max_size=300), signed=st.booleans())
def test_hypothesis_whole_stream_of_frames(data, signed):
    """Frames back to back parse one for one; the bytes fed are all accounted for."""
    rnd = random.Random(data)
    frames, expect = [], []
    for _ in range(rnd.randint(1, 20)):
        version = rnd.choice([1, 2])
        cls = rnd.choice(classes("common", version))
        values = random_values(cls, rnd)
        s = version == 2 and signed
        fr = pack("common", version, cls, values, rnd.getrandbits(8), 1, 1, SIGN_KEY if s else None)
        frames.append(fr)
        expect.append(full_payload(fr, "common", cls.id))
    got, p = parse("common", b"".join(frames))
    assert [g["payload"] for g in got] == expect
    assert p.bytes_discarded == 0 and p.frames == len(frames)


# --- MicroPython: batches through wire_tool -------------------------------------------


def batch(dialect, rnd, rounds):
    """(version, cls, values, seq, sysid, compid, signed) for every message, `rounds` times."""
    out = []
    for version in (1, 2):
        for r in range(rounds):
            for cls in classes(dialect, version):
                out.append((version, cls, random_values(cls, rnd), rnd.getrandbits(8),
                            rnd.getrandbits(8), rnd.getrandbits(8), version == 2 and r % 3 == 2))
    return out


@pytest.mark.parametrize("portable", [False, True], ids=["viper", "portable"])
@pytest.mark.parametrize("dialect", ["common", "seed2012"])
def test_micropython_parses_and_encodes_every_message(tmp_path, dialect, portable):
    rnd = random.Random(dialect + str(portable))
    cases = batch(dialect, rnd, 5 if dialect == "common" else 10)
    frames = [pack(dialect, v, cls, vals, seq, sysid, compid, SIGN_KEY if signed else None)
              for v, cls, vals, seq, sysid, compid, signed in cases]
    stream = tmp_path / "frames.bin"
    stream.write_bytes(b"".join(frames))
    # Encode input: the full payloads, which the tool unpacks and packs again with FMT.
    enc_in = tmp_path / "encode.txt"
    with open(enc_in, "w") as f:
        for (v, cls, vals, seq, sysid, compid, signed), fr in zip(cases, frames):
            f.write("%d %d %d %d %d %s\n" % (v, cls.id, seq, sysid, compid,
                                             full_payload(fr, dialect, cls.id).hex()))
    parsed, enc_out = tmp_path / "parsed.txt", tmp_path / "encoded.txt"
    run_tool(["parse", dialect, "r11", parsed, stream], portable)
    run_tool(["encode", dialect, enc_in, enc_out], portable)

    [(got, stats)] = read_parsed(parsed)
    assert stats["frames"] == len(cases) and stats["bytes_discarded"] == 0
    assert len(got) == len(cases)
    for (v, cls, vals, seq, sysid, compid, signed), fr, g in zip(cases, frames, got):
        assert (g["version"], g["msgid"], g["seq"], g["sysid"], g["compid"], g["signed"]) == (
            v, cls.id, seq, sysid, compid, signed)
        assert g["payload"] == full_payload(fr, dialect, cls.id), cls.msgname
        assert g["signature"] == (fr[-13:] if signed else b"")
        unpacked = struct.unpack(OURS[dialect].FMT[cls.id], g["payload"])
        assert same(list(unpacked), full_values(dialect, cls, vals)), cls.msgname

    encoded = enc_out.read_text().split()
    assert len(encoded) == len(cases)
    for (v, cls, vals, seq, sysid, compid, signed), fr, e in zip(cases, frames, encoded):
        ours = bytes.fromhex(e)
        if not signed and not has_nan(vals):
            assert ours == fr, cls.msgname  # byte for byte pymavlink's frame
        check_decoded(dialect, v, ours, cls, vals, seq, sysid, compid)


def test_mavlink1_frame_with_extension_bytes_is_accepted():
    """A MAVLink 1 frame longer than the base fields (pymavlink's v2 module forced to
    v1, the C library) carries the extensions too; up to the full length is valid."""
    from pymavlink.dialects.v20 import common as v2
    from mavstack.dialects import common as dialect
    from mavstack.parser import Parser

    mav = v2.MAVLink(None, srcSystem=9, srcComponent=8)
    frame = mav.mission_count_encode(1, 1, 7, 2).pack(mav, force_mavlink1=True)
    assert frame[0] == 0xFE and frame[1] > dialect.CRC_LEN[44] >> 8 & 0xFF
    got = []
    p = Parser(dialect.CRC_LEN, lambda msgid, payload: got.append((msgid, bytes(payload[:5]))))
    p.feed(frame)
    assert got == [(44, bytes([7, 0, 1, 1, 2]))] and p.bad_frames == 0
    too_long = bytearray(frame)
    too_long[1] = (dialect.CRC_LEN[44] >> 16) + 1
    p.feed(too_long)
    assert len(got) == 1 and p.bad_frames == 1
