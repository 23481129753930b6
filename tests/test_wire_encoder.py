"""Encoder and Link transmit side: MAVLink 2 trims trailing zeros but never the first byte,
sequence numbers wrap at 256 per link, source system/component, MAVLink 1 only for ids
up to 255; checked against pymavlink's decoder."""
import struct

import pytest

from mavstack.encoder import Encoder
from mavstack.endpoint import Endpoint
from wire_oracle import OURS, MemoryTransport, decode_frames, reference

COMMON = OURS["common"]
CRC_LEN = COMMON.CRC_LEN
FMT = COMMON.FMT
M2 = reference("common", 2)
ATTITUDE, HEARTBEAT, PARAM_VALUE, SYS_STATUS, COMMAND_ACK = 30, 0, 22, 1, 77
SETUP_SIGNING = 256  # id > 255: MAVLink 2 only


def encode(enc, msgid, values, sysid=1, compid=1):
    off = enc.begin()
    struct.pack_into(FMT[msgid], enc.buf, off, *values)
    n = enc.finish(msgid, sysid, compid)
    return bytes(enc.buf[:n])


def zeros(msgid):
    return list(struct.unpack(FMT[msgid], bytes(CRC_LEN[msgid] >> 16)))


@pytest.mark.parametrize("values,plen", [
    ([0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1),  # all zero: the first byte stays
    ([1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1),
    ([0x100, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 2),
    ([0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], 16),  # zeros inside stay, only the tail goes
    ([0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.0], 28),  # -0.0 is not zero bytes
    ([1, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], 28),
])
def test_v2_trims_trailing_zeros_never_the_first_byte(values, plen):
    enc = Encoder(CRC_LEN, 2)
    # A longer frame first, so that stale bytes in the buffer would show.
    encode(enc, ATTITUDE, [9, 9.0, 9.0, 9.0, 9.0, 9.0, 9.0])
    f = encode(enc, ATTITUDE, values)
    assert f[1] == plen and len(f) == 10 + plen + 2
    [m] = decode_frames("common", 2, f)
    assert m.get_type() == "ATTITUDE"
    got = [m.time_boot_ms, m.roll, m.pitch, m.yaw, m.rollspeed, m.pitchspeed, m.yawspeed]
    assert got == values and str(m.yawspeed) == str(values[-1])


def test_sequence_wraps_at_256_and_source_ids():
    enc = Encoder(CRC_LEN, 2)
    frames = [encode(enc, HEARTBEAT, [i, 2, 3, 81, 4, 3], sysid=42, compid=191) for i in range(600)]
    msgs = decode_frames("common", 2, b"".join(frames))
    assert [m.get_seq() for m in msgs] == [i & 0xFF for i in range(600)]
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in msgs} == {(42, 191)}
    assert [m.custom_mode for m in msgs] == list(range(600))
    assert enc.frames == 600 and enc.seq == 600 & 0xFF


def test_v1_only_for_ids_up_to_255():
    enc = Encoder(CRC_LEN, 1)
    assert SETUP_SIGNING in CRC_LEN
    assert encode(enc, SETUP_SIGNING, zeros(SETUP_SIGNING)) == b""
    assert enc.finish(0xABCDEF, 1, 1) == 0  # unknown: not sendable in either version
    assert enc.seq == 0 and enc.frames == 0  # refused frames use no sequence number
    f = encode(enc, HEARTBEAT, [5, 2, 3, 81, 4, 3], sysid=7, compid=8)
    assert f[0] == 0xFE and f[1] == 9 and f[2] == 0 and f[3:6] == bytes([7, 8, 0])
    [m] = decode_frames("common", 1, f)
    assert m.get_type() == "HEARTBEAT" and m.custom_mode == 5
    enc2 = Encoder(CRC_LEN, 2)
    assert encode(enc2, SETUP_SIGNING, zeros(SETUP_SIGNING))[0] == 0xFD


def test_v1_sends_base_fields_only():
    """SYS_STATUS gained extension fields in MAVLink 2: MAVLink 1 carries its 31 bytes."""
    enc = Encoder(CRC_LEN, 1)
    values = zeros(SYS_STATUS)
    values[:13] = [1, 2, 3, 4, 5, -6, 7, 8, 9, 10, 11, 12, -13]
    values[13:] = [0xFFFFFFFF] * (len(values) - 13)
    f = encode(enc, SYS_STATUS, values)
    assert f[1] == (CRC_LEN[SYS_STATUS] >> 8) & 0xFF == 31
    [m] = decode_frames("common", 1, f)
    assert m.get_type() == "SYS_STATUS" and m.battery_remaining == -13
    [m2] = decode_frames("common", 2, f)  # a MAVLink 2 reader zero-fills the extensions
    assert m2.onboard_control_sensors_present_extended == 0


def test_link_negotiates_version_and_counts():
    ep = Endpoint(COMMON, sysid=3, compid=1)
    t = MemoryTransport()
    link = ep.add_link(t)
    assert link.version == 1
    off = link.begin()
    struct.pack_into(FMT[HEARTBEAT], link.txbuf, off, 0, 2, 3, 81, 4, 3)
    assert link.send(HEARTBEAT)
    assert not link.send(SETUP_SIGNING)  # no MAVLink 1 form: not sent
    assert t.tx[0] == 0xFE
    # A MAVLink 2 frame from the peer switches the link to MAVLink 2.
    m = M2.MAVLink(None, 255, 190)
    t.rx += M2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(m)
    ep.poll(0)
    assert link.rx.frames == 1 and link.version == 2
    off = link.begin()
    struct.pack_into(FMT[HEARTBEAT], link.txbuf, off, 0, 2, 3, 81, 4, 3)
    assert link.send(HEARTBEAT, compid=5)
    msgs = decode_frames("common", 2, bytes(t.tx))
    assert [x.get_msgbuf()[0] for x in msgs] == [0xFE, 0xFD]
    assert [(x.get_seq(), x.get_srcSystem(), x.get_srcComponent()) for x in msgs] == [(0, 3, 1), (1, 3, 5)]
    assert link.tx_bytes == len(t.tx)
    t.accept = False
    assert not link.send(HEARTBEAT) and link.tx_dropped == 1


def test_send_payload_zeroes_what_the_payload_does_not_cover():
    ep = Endpoint(COMMON, sysid=1, compid=1)
    t = MemoryTransport()
    link = ep.add_link(t, version=2)
    full = bytearray(struct.pack(FMT[ATTITUDE], 9, 9.0, 9.0, 9.0, 9.0, 9.0, 9.0))
    assert link.send_payload(ATTITUDE, full, len(full))
    short = struct.pack("<I", 77)
    assert link.send_payload(ATTITUDE, short, len(short))
    a, b = decode_frames("common", 2, bytes(t.tx))
    assert a.roll == 9.0 and (b.time_boot_ms, b.roll, b.yawspeed) == (77, 0.0, 0.0)
    assert b.get_msgbuf()[1] == 1


def test_separate_links_keep_separate_sequences():
    ep = Endpoint(COMMON, sysid=1, compid=1)
    ta, tb = MemoryTransport(), MemoryTransport()
    la, lb = ep.add_link(ta, version=2), ep.add_link(tb, version=2)
    payload = struct.pack(FMT[HEARTBEAT], 0, 2, 3, 81, 4, 3)
    for i in range(300):
        la.send_payload(HEARTBEAT, payload, len(payload))
        if i % 3 == 0:
            lb.send_payload(HEARTBEAT, payload, len(payload))
    sa = [m.get_seq() for m in decode_frames("common", 2, bytes(ta.tx))]
    sb = [m.get_seq() for m in decode_frames("common", 2, bytes(tb.tx))]
    assert sa == [i & 0xFF for i in range(300)] and sb == list(range(100))
