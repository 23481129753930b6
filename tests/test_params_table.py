"""The parameter service in-process on CPython, pymavlink encoding and decoding the frames,
and its steady state under MicroPython's heap_lock()."""
import math
import os
import struct
import sys

import pytest

from conftest import ROOT, run_mpy

from pymavlink.dialects.v20 import common as mav

from mavstack.dialects import common
from mavstack.endpoint import Endpoint
from mavstack.kernels import crc16
from mavstack.services import commands as commands_service
from mavstack.services import params as P
from mavstack.services import status as status_service
from mavstack.services.params import table as param_table
from mavstack.storage import Storage

sys.path.insert(0, os.path.join(ROOT, "boards"))
import unix_params  # noqa: E402

TABLE = unix_params.PARAMS
N = len(TABLE)
NAMES = [row[0] for row in TABLE]
# One parameter of every type the service takes (the unix table is INT32 and REAL32).
MIXED = (
    ("U8", P.UINT8, 7, 0, 200),
    ("I8", P.INT8, -3, -100, 100),
    ("U16", P.UINT16, 1000),
    ("I16", P.INT16, -1000),
    ("U32", P.UINT32, 12345),
    ("I32", P.INT32, -5),
    ("F", P.REAL32, 1.5, -10.0, 10.0),
    ("RO", P.UINT8, 1, 0, 255, P.READ_ONLY),
)


def as_float(fmt, v):
    """The float whose 4 bytes are v packed as fmt (bytewise encoding)."""
    return struct.unpack("<f", struct.pack(fmt, v).ljust(4, b"\0"))[0]


class MemTransport:
    """An in-memory link: bytes in from the ground station, bytes out to it."""

    def __init__(self, bytes_per_s=200000, name="mem"):
        self.bytes_per_s = bytes_per_s
        self.name = name
        self.inbox = bytearray()
        self.out = bytearray()

    def readinto(self, buf):
        n = min(len(buf), len(self.inbox))
        buf[:n] = self.inbox[:n]
        del self.inbox[:n]
        return n

    def write(self, buf, n):
        self.out += bytes(buf[:n])
        return n

    def close(self):
        pass


class Texts:
    """Stands where the status service would: collects STATUSTEXTs."""

    NAME = "status"
    conventions = None  # no ground station's conventions known: "auto" is bytewise

    def __init__(self):
        self.texts = []

    def attach(self, ep):
        pass

    def statustext(self, severity, text):
        # Bytes may be a NUL-padded buffer (the text field's form), as the real queue takes them.
        self.texts.append(bytes(text).split(b"\0")[0].decode() if isinstance(text, (bytes, bytearray)) else text)


class Rig:
    """An endpoint with the params and commands services, and pymavlink peers per link."""

    def __init__(self, tmp_path, table=TABLE, links=1, version=2, rate=200000, status=False, **kw):
        self.ep = Endpoint(common, 1, 1)
        self.ep.storage = Storage(str(tmp_path / "storage"))
        self.transports = []
        for i in range(links):
            t = MemTransport(rate, "mem%d" % i)
            self.transports.append(t)
            self.ep.add_link(t, version)
        self.texts = Texts()
        self.ep.add(self.texts)
        if status:  # the conventions each link's ground station assumes ("auto")
            status_service.create(self.ep)
        self.params = self.ep.add(P.Params(table, **kw))
        commands_service.create(self.ep)
        self.mav = [mav.MAVLink(None, 255, 190) for _ in range(links)]
        self.now = 1000
        for i in range(links):  # a station on every link (a link nobody spoke on is told no changes)
            self.send(mav.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3), i)
        self.poll()
        for i in range(links):
            self.received(i)

    def send(self, msg, link=0):
        self.transports[link].inbox += msg.pack(self.mav[link])

    def poll(self, ms=1):
        for _ in range(ms):
            self.ep.poll(self.now)
            self.now += 1

    def received(self, link=0):
        data = bytes(self.transports[link].out)
        self.transports[link].out.clear()
        out = []
        for m in self.mav[link].parse_buffer(data) or []:
            out.append(m)
        return out

    def values(self, link=0):
        return [m for m in self.received(link) if m.get_type() == "PARAM_VALUE"]

    def ask(self, msg, link=0):
        self.texts.texts.clear()
        self.send(msg, link)
        self.poll()
        return self.received(link)

    def set(self, name, value, ptype, link=0, target=(1, 1)):
        return self.ask(mav.MAVLink_param_set_message(target[0], target[1], name.encode(), value, ptype), link)

    def command(self, command, *params):
        params = list(params) + [0.0] * (7 - len(params))
        return self.ask(mav.MAVLink_command_long_message(1, 1, command, 0, *params))

    def listed(self, link=0, limit_ms=20000):
        got = []
        for _ in range(limit_ms):
            self.poll()
            got += self.values(link)
            if len(got) >= self.params.count:
                break
        return got


def raw_value(m):
    """param_value's 4 bytes exactly as they travelled."""
    buf = m.get_msgbuf()
    off = 10 if buf[0] == 0xFD else 6
    return bytes(buf[off:off + 4])


# --- declaration ------------------------------------------------------------------

@pytest.mark.parametrize("row, message", [
    (("BIG", P.INT64, 0), "64-bit"),
    (("BIG", P.UINT64, 0), "64-bit"),
    (("BIG", P.REAL64, 0.0), "64-bit"),
    (("X" * 17, P.REAL32, 0.0), "1..16"),
    (("", P.REAL32, 0.0), "1..16"),
    (("SPEED", P.REAL32, 40.0, 0.0, 30.0), "default"),
    (("COUNT", P.UINT8, 300), "default"),
    (("COUNT", P.UINT8, 3, 0, 1000), "range"),
    (("HALF", P.INT32, 1.5), "whole"),
    (("ODD", 42, 0), "MAV_PARAM_TYPE"),
    (("SP ACE", P.UINT8, 0), "printable"),
])
def test_declaration_errors(row, message):
    with pytest.raises(ValueError, match=message):
        P.Params((row,))


def test_declared_twice():
    with pytest.raises(ValueError, match="twice"):
        P.Params((("A", P.UINT8, 1), ("A", P.INT8, 1)))


def test_hash_collisions_resolved_by_compare():
    by_hash = {}
    names = None
    for k in range(100000):
        name = "P%06d" % k
        h = crc16(name.encode(), 0, len(name), 0xFFFF)
        if h in by_hash:
            names = (by_hash[h], name)
            break
        by_hash[h] = name
    assert names
    table = tuple((n, P.INT32, i) for i, n in enumerate(names + ("OTHER",)))
    p = P.Params(table)
    assert [p.get(n) for n in names] == [0, 1]
    assert p.index(names[1]) == 1
    with pytest.raises(KeyError):
        p.index("P999999")


# --- protocol ---------------------------------------------------------------------

@pytest.mark.parametrize("version", [1, 2])
def test_list_in_order_with_count(tmp_path, version):
    b = Rig(tmp_path, version=version)
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    got = b.listed()
    assert [m.param_index for m in got] == list(range(N))
    assert all(m.param_count == N for m in got)
    assert [m.param_id for m in got] == NAMES
    assert all(m.get_header().srcSystem == 1 for m in got)
    # Defaults, decoded the way a bytewise ground station decodes them.
    for m, row in zip(got, TABLE):
        assert m.param_type == row[1]
        if row[1] == P.REAL32:
            assert m.param_value == pytest.approx(row[2], rel=1e-6)
        else:
            fmt = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i"}[row[1]]
            assert raw_value(m) == struct.pack(fmt, row[2]).ljust(4, b"\0")


def test_list_takes_the_link_budget_but_never_bursts_past_it(tmp_path):
    b = Rig(tmp_path, rate=5760)
    # The first list of a quiet link also spends the bucket it saved up; the figure is
    # the second, with the bucket as a busy link has it.
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    b.listed()
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    start = b.now
    got = b.listed()
    elapsed_ms = b.now - start
    wire = sum(len(m.get_msgbuf()) for m in got)
    bound_ms = wire * 1000 / 5760
    assert len(got) == N
    # No streams here: the whole link, within a few frames, never faster than it.
    assert 0.95 * bound_ms < elapsed_ms < 1.15 * bound_ms, (elapsed_ms, bound_ms)


def test_a_list_held_by_the_budget_sleeps_until_there_is_room(tmp_path):
    """While the budget holds the next value back, the loop may sleep until the bucket
    has room for it (Link.ready_in): a pass a value, not a pass a millisecond."""
    b = Rig(tmp_path, rate=5760)
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    b.listed()  # (the first list spends the bucket a quiet link saved up)
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    got, passes = [], 0
    while len(got) < N:
        b.ep.poll(b.now)
        passes += 1
        b.now += max(1, b.ep.wait_ms)
        got += b.values()
    assert [m.param_index for m in got] == list(range(N))
    assert passes < 1.5 * N  # 37 bytes a value: 6.4 ms of the link between them


def test_list_asked_again_continues_and_other_links_are_undisturbed(tmp_path):
    b = Rig(tmp_path, links=2, rate=5760)
    b.send(mav.MAVLink_param_request_list_message(1, 1), link=0)
    b.send(mav.MAVLink_param_request_list_message(1, 1), link=1)
    b.poll(300)
    first0 = b.values(0)
    first1 = b.values(1)
    assert 5 < len(first0) < N
    for _ in range(5):  # asked again and again: still one list
        b.send(mav.MAVLink_param_request_list_message(1, 1), link=0)
        b.poll(20)
    rest0 = first0 + b.listed(0)[:N]  # (a pass may send a few: listed can read past N)
    rest1 = first1 + b.values(1)
    while len(rest1) < N:
        b.poll(10)
        rest1 += b.values(1)
    # Link 0: the first list up to where it was asked again, then every value once,
    # from there on round to where that was: each index in all, N + len(first0) frames.
    k = len(first0)
    assert [m.param_index for m in rest0] == list(range(k)) + list(range(k, N)) + list(range(k))
    assert [m.param_index for m in rest1] == list(range(N))  # undisturbed


def test_list_for_another_system_is_ignored(tmp_path):
    b = Rig(tmp_path)
    b.send(mav.MAVLink_param_request_list_message(2, 1))
    b.send(mav.MAVLink_param_request_list_message(1, 5))
    b.poll(100)
    assert b.values() == []
    b.send(mav.MAVLink_param_request_list_message(0, 0))  # broadcast
    assert len(b.listed()) == N


@pytest.mark.parametrize("name", ["SIM_GPS_GLITCH_M", "MOT_SPOOL_TIME_S", "RTL_LOIT_TIME_S", "WP_SPEED"])
def test_read_by_name_including_16_chars(tmp_path, name):
    assert len(name) in (16, 15, 8)
    b = Rig(tmp_path)
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, name.encode(), -1))
    assert len(got) == 1
    assert got[0].param_id == name and got[0].param_index == NAMES.index(name)
    raw = got[0].get_msgbuf()
    off = 10 if raw[0] == 0xFD else 6
    name_field = bytes(raw[off + 8:off + 24])
    assert name_field == name.encode().ljust(16, b"\0")  # no NUL when 16 long


def test_read_by_index_ignores_the_name(tmp_path):
    b = Rig(tmp_path)
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, b"WP_SPEED", 3))
    assert [(m.param_id, m.param_index) for m in got] == [(NAMES[3], 3)]


@pytest.mark.parametrize("name, index", [(b"NO_SUCH_PARAM", -1), (b"WP_SPEEDX", -1), (b"WP_SPEE", -1),
                                         (b"", -1), (b"", N), (b"", 30000)])
def test_read_unknown_gets_param_error_and_statustext(tmp_path, name, index):
    b = Rig(tmp_path)
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, name, index))
    assert [m.get_type() for m in got] == ["PARAM_ERROR"]
    assert got[0].error == 1 and got[0].param_index == index and got[0].param_id == name.decode()
    assert len(b.texts.texts) == 1 and "unknown" in b.texts.texts[0]


def test_set_float_answered_and_broadcast(tmp_path):
    b = Rig(tmp_path, links=2)
    changes = []
    b.params.on_change = lambda name, value: changes.append((name, value))
    got = b.set("SIM_SPEED", 7.25, P.REAL32)
    assert [(m.param_id, m.param_value) for m in got] == [("SIM_SPEED", 7.25)]
    b.poll(5)
    other = b.values(1)
    assert [(m.param_id, m.param_value, m.param_index) for m in other] == [
        ("SIM_SPEED", 7.25, NAMES.index("SIM_SPEED"))]
    assert changes == [("SIM_SPEED", 7.25)]
    assert b.params.get("SIM_SPEED") == 7.25


@pytest.mark.parametrize("name, ptype, fmt, value", [
    ("BATT_CAPACITY", P.INT32, "<i", 6000),
    ("I32", P.INT32, "<i", -2000000000),
    ("U32", P.UINT32, "<I", 3000000000),
    ("I16", P.INT16, "<h", -4500),
    ("U16", P.UINT16, "<H", 60000),
    ("I8", P.INT8, "<b", -1),
    ("U8", P.UINT8, "<B", 200),
])
def test_set_int_bytewise(tmp_path, name, ptype, fmt, value):
    b = Rig(tmp_path, table=TABLE if name in NAMES else MIXED)
    got = b.set(name, as_float(fmt, value), ptype)
    assert len(got) == 1 and got[0].param_type == ptype
    assert raw_value(got[0]) == struct.pack(fmt, value).ljust(4, b"\0")
    assert b.params.get(name) == value
    assert b.texts.texts == []


def test_mixed_types_listed_bytewise(tmp_path):
    b = Rig(tmp_path, table=MIXED)
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    got = b.listed()
    assert [raw_value(m) for m in got] == [
        b"\x07\0\0\0", b"\xfd\0\0\0", struct.pack("<I", 1000), struct.pack("<hh", -1000, 0),
        struct.pack("<I", 12345), struct.pack("<i", -5), struct.pack("<f", 1.5), b"\x01\0\0\0"]
    assert [m.param_type for m in got] == [row[1] for row in MIXED]


@pytest.mark.parametrize("name, value, ptype, reason, error", [
    ("SIM_SPEED", 45.0, P.REAL32, "range", 2),  # MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    ("SIM_SPEED", 0.1, P.REAL32, "range", 2),
    ("SIM_SPEED", float("nan"), P.REAL32, "NaN", 2),
    ("SIM_SPEED", float("inf"), P.REAL32, "finite", 2),
    ("SIM_SPEED", -float("inf"), P.REAL32, "finite", 2),
    ("SIM_SPEED", as_float("<i", 6), P.INT32, "type", 7),  # TYPE_MISMATCH
    ("BATT_CAPACITY", 6000.5, P.REAL32, "whole", 2),  # declared a float: a cast
    ("BATT_CAPACITY", -5.0, P.REAL32, "range", 2),
    ("BATT_CAPACITY", as_float("<i", -5), P.INT32, "range", 2),
    ("U8", as_float("<B", 201), P.UINT8, "range", 2),
    ("I8", as_float("<b", -101), P.INT8, "range", 2),
    ("U8", as_float("<i", 12), P.INT32, "type", 7),
    ("MAV_SYS_ID", as_float("<i", 7), P.INT32, "read-only", 5),  # READ_ONLY
    ("RO", as_float("<B", 7), P.UINT8, "read-only", 5),
])
def test_set_refused_keeps_value(tmp_path, name, value, ptype, reason, error):
    b = Rig(tmp_path, table=TABLE if name in NAMES else MIXED, links=2)
    before = b.params.get(name)
    got = b.set(name, value, ptype)
    assert [m.get_type() for m in got] == ["PARAM_ERROR", "PARAM_VALUE"]
    assert got[0].param_id == name and got[0].error == error
    got = got[1:]
    assert len(got) == 1 and got[0].param_id == name
    assert b.params.get(name) == before
    if isinstance(before, float):
        assert got[0].param_value == pytest.approx(before)
    assert len(b.texts.texts) == 1 and reason in b.texts.texts[0] and name in b.texts.texts[0]
    b.poll(5)
    assert b.values(1) == []  # nothing changed: nothing to tell the others


@pytest.mark.parametrize("name", ["SIM_GPS_GLITCH_M", "RTL_LOIT_TIME_S"])
def test_set_16_and_15_char_names(tmp_path, name):
    b = Rig(tmp_path)
    got = b.set(name, 1.25, P.REAL32)
    assert [(m.param_id, m.param_value) for m in got] == [(name, 1.25)]
    assert b.params.get(name) == 1.25


def test_name_padding_after_nul_is_ignored(tmp_path):
    b = Rig(tmp_path)
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, b"WP_SPEED\0junk!!!", -1))
    assert [m.param_id for m in got] == ["WP_SPEED"]


def test_unprintable_unknown_name_is_reported_safely(tmp_path):
    b = Rig(tmp_path)
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, b"\xff\xfeBAD\x01NAME\x80\x90", -1))
    assert [m.get_type() for m in got] == ["PARAM_ERROR"]  # the name as it came
    assert b.texts.texts == ["unknown param ??BAD?NAME??"]


def test_set_unknown_and_foreign_targets(tmp_path):
    b = Rig(tmp_path)
    assert [m.error for m in b.set("NO_SUCH", 1.0, P.REAL32)] == [1]  # PARAM_ERROR DOES_NOT_EXIST
    assert "unknown" in b.texts.texts[0]
    assert b.set("SIM_SPEED", 8.0, P.REAL32, target=(2, 1)) == []
    assert b.set("SIM_SPEED", 8.0, P.REAL32, target=(1, 2)) == []
    assert b.texts.texts == [] and b.params.get("SIM_SPEED") == 5.0
    assert len(b.set("SIM_SPEED", 8.0, P.REAL32, target=(0, 0))) == 1


def test_set_refused_without_operator_control(tmp_path):
    b = Rig(tmp_path)

    class NotYou:
        sysid = 200  # another ground station is in control (link.py ranks by it)

        def allows(self, link):
            return False

    b.ep.operator = NotYou()
    got = b.set("SIM_SPEED", 8.0, P.REAL32)
    assert [m.error for m in got[:1]] == [3]  # PARAM_ERROR PERMISSION_DENIED
    got = got[1:]
    assert [m.param_value for m in got] == [5.0]
    assert "control" in b.texts.texts[0]
    acks = [m for m in b.command(180, NAMES.index("SIM_SPEED"), 9.0) if m.get_type() == "COMMAND_ACK"]
    assert [a.result for a in acks] == [2]  # DENIED
    assert b.params.get("SIM_SPEED") == 5.0


def test_reboot_flag_is_reported(tmp_path):
    b = Rig(tmp_path)
    b.set("SERIAL1_BAUD", as_float("<i", 115200), P.INT32)
    assert any("reboot" in t for t in b.texts.texts)


def test_c_cast_encoding(tmp_path):
    b = Rig(tmp_path, table=MIXED, encoding="c_cast")
    assert b.ep.capabilities & (1 << 17) and not b.ep.capabilities & (1 << 4)
    b.send(mav.MAVLink_param_request_list_message(1, 1))
    got = {m.param_id: m for m in b.listed()}
    assert [got[row[0]].param_value for row in MIXED] == [7.0, -3.0, 1000.0, -1000.0, 12345.0, -5.0, 1.5, 1.0]
    assert b.set("I32", 6000.0, P.INT32)[0].param_value == 6000.0
    # A C-cast ground station may tag every value REAL32: the value is still the number.
    assert b.set("U32", 3000000000.0, P.REAL32)[0].param_value == 3000000000.0
    assert b.params.get("U32") == 3000000000
    assert b.set("I32", 6000.5, P.INT32)[1].param_value == 6000.0
    assert "whole" in b.texts.texts[0]
    assert b.set("I8", -101.0, P.INT8)[1].param_value == -3.0
    assert "range" in b.texts.texts[0]
    assert b.set("I8", -100.0, P.REAL32)[0].param_value == -100.0
    assert b.params.get("I8") == -100


def test_bytewise_encoding_takes_real32_typed_integers_as_casts(tmp_path):
    b = Rig(tmp_path, table=MIXED)
    got = b.set("I32", 6000.0, P.REAL32)
    assert [m.get_type() for m in got] == ["PARAM_VALUE"] and b.params.get("I32") == 6000
    assert got[0].get_msgbuf()[10:14] == struct.pack("<i", 6000)  # bytewise stays bytewise
    assert b.set("U32", 3000000000.0, P.REAL32)[0].get_msgbuf()[10:14] == struct.pack("<I", 3000000000)
    assert [m.error for m in b.set("I8", 1.5, P.REAL32)[:1]] == [2]
    assert b.params.get("I8") == -3


def test_auto_encoding_per_link(tmp_path):
    """"auto": C-cast on a link whose ground station shows ArduPilot's conventions (the
    status service's conventions.py), bytewise elsewhere; a REAL32-typed set of an
    integer is the number it holds and changes no link's encoding, but from a station in
    PX4's convention it is refused (PX4's rule: TYPE_MISMATCH, nothing stored)."""
    b = Rig(tmp_path, table=MIXED, encoding="auto", links=2, status=True)
    assert b.ep.capabilities & (1 << 4) and not b.ep.capabilities & (1 << 17)  # told: bytewise

    def value(msgs):
        return [m for m in msgs if m.get_type() == "PARAM_VALUE"][-1]

    got = b.set("I32", 6000.0, P.REAL32)  # nothing shown yet: the number, answered bytewise
    assert value(got).get_msgbuf()[10:14] == struct.pack("<i", 6000)
    b.send(mav.MAVLink_request_data_stream_message(1, 1, 0, 4, 1), 1)  # ArduPilot's way: C-cast
    assert value(b.ask(mav.MAVLink_param_request_read_message(1, 1, b"I32", -1), 1)).param_value == 6000.0
    b.command(512, 148.0)  # asks for AUTOPILOT_VERSION on link 0: PX4's, as nothing else was shown
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, b"I32", -1))
    assert value(got).get_msgbuf()[10:14] == struct.pack("<i", 6000)
    got = b.set("I32", 7000.0, P.REAL32)  # a float for an integer from PX4's side: refused
    assert [m.error for m in got if m.get_type() == "PARAM_ERROR"] == [7]  # TYPE_MISMATCH
    assert b.params.get("I32") == 6000
    assert value(b.set("I32", 7000.0, P.REAL32, link=1)).param_value == 7000.0  # ArduPilot's: taken
    assert b.params.get("I32") == 7000
    b.send(mav.MAVLink_request_data_stream_message(1, 1, 0, 4, 1), 0)  # shown later: C-cast
    assert value(b.ask(mav.MAVLink_param_request_read_message(1, 1, b"I32", -1))).param_value == 7000.0
    b.command(512, 148.0)  # decides only a link that has shown nothing
    got = b.ask(mav.MAVLink_param_request_read_message(1, 1, b"I32", -1))
    assert value(got).param_value == 7000.0


def test_bytewise_capability(tmp_path):
    b = Rig(tmp_path)
    assert b.ep.capabilities & (1 << 4) and not b.ep.capabilities & (1 << 17)


def test_do_set_parameter(tmp_path):
    b = Rig(tmp_path, links=2)
    i = NAMES.index("BATT_CAPACITY")
    got = b.command(180, i, 7000.0)
    b.poll(5)
    got += b.received()
    # The ACK first, then the new value on every link.
    assert [m.get_type() for m in got] == ["COMMAND_ACK", "PARAM_VALUE"]
    assert got[0].result == 0 and got[1].param_id == "BATT_CAPACITY"
    assert b.params.get("BATT_CAPACITY") == 7000
    assert [m.param_id for m in b.values(1)] == ["BATT_CAPACITY"]
    for args in ((i, 7000.5), (i, -1.0), (N, 1.0), (-1, 1.0), (float("nan"), 1.0), (i, float("nan")),
                 (NAMES.index("MAV_SYS_ID"), 3.0), (NAMES.index("SIM_SPEED"), float("inf"))):
        acks = [m for m in b.command(180, *args) if m.get_type() == "COMMAND_ACK"]
        assert [a.result for a in acks] == [2], args
    assert b.params.get("BATT_CAPACITY") == 7000
    acks = [m for m in b.command(180, NAMES.index("SIM_SPEED"), 12.5) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 0 and b.params.get("SIM_SPEED") == 12.5


# --- 32-bit values: keys and conversions on bytes, against Python's numbers ---------

_FMT = {P.UINT8: "<B", P.INT8: "<b", P.UINT16: "<H", P.INT16: "<h", P.UINT32: "<I", P.INT32: "<i"}
_EDGES = [0, 1, -1, 127, -128, 255, 256, 32767, -32768, 65535, 2 ** 24, 2 ** 24 + 1, 2 ** 24 + 2,
          2 ** 24 + 3, 2 ** 25 + 2, 2 ** 25 + 6, 2 ** 30 - 1, 2 ** 30, -2 ** 30, -2 ** 30 - 1,
          2 ** 31 - 1, -2 ** 31, -2 ** 31 + 1, 2 ** 31, 2 ** 32 - 1, 2 ** 32 - 129, 2 ** 32 - 128,
          3000000000, -1500000000, 0x7FFFFF80, 0x7FFFFFBF, 0x7FFFFFC0]


def _f32(v):
    return struct.unpack("<f", struct.pack("<f", v))[0]


def _samples(rng, lo, hi):
    """Edge values within lo..hi, and random ones of every magnitude."""
    out = [v for v in _EDGES if lo <= v <= hi] + [lo, hi]
    for _ in range(300):
        bits = rng.randint(0, (hi - lo).bit_length())
        out.append(min(hi, max(lo, lo + rng.getrandbits(bits) if bits else lo)))
    return out


@pytest.mark.parametrize("t", sorted(_FMT))
def test_c_cast_wire_is_the_c_conversion(t):
    """Integers in C-cast travel as (float)value: nearest, ties to even, from the bytes."""
    import random

    rng = random.Random(t)
    lo, hi = param_table._INT_RANGE[t]
    table = P.Params((("V", t, 0),), encoding="c_cast")
    for v in _samples(rng, lo, hi):
        table.put(0, v)
        assert bytes(table._wire) == struct.pack("<f", v), v
        assert table.get("V") == v


@pytest.mark.parametrize("t", [P.UINT32, P.INT32, P.INT16, P.UINT8])
def test_floats_cast_to_integers(t):
    """C-cast PARAM_SET and DO_SET_PARAMETER: a float holding an integer, read on its bits."""
    import random

    rng = random.Random(t)
    lo, hi = param_table._INT_RANGE[t]
    table = P.Params((("V", t, 0),), encoding="c_cast")
    floats = [_f32(v) for v in _EDGES] + [0.5, -0.5, 1.5, 1e-30, -0.0, 2.0 ** 40, -2.0 ** 40, 4294967040.0,
                                          4294967296.0, 2147483520.0, 2147483648.0, -2147483648.0,
                                          -2147483904.0, 3e9, -1.5e9, 4e9]
    floats += [_f32(rng.uniform(-5e9, 5e9)) for _ in range(300)]
    floats += [_f32(rng.uniform(-300, 300)) for _ in range(100)]
    for f in floats:
        table.put(0, 0)
        why = table.accept(0, struct.pack("<f", f), 0, True)
        if f != int(f):
            assert why == "not a whole number", f
        elif not lo <= int(f) <= hi:
            assert why.startswith("out of range"), f
        else:
            assert why is None and table.get("V") == int(f), f
            assert bytes(table._values) == struct.pack(_FMT[t], int(f)).ljust(4, b"\0")


def test_ranges_compare_as_numbers():
    """Keys order like the numbers: ranges of every sign and size, floats and ints."""
    import random

    rng = random.Random(3)
    for _ in range(200):
        a, b = sorted(_f32(rng.choice([1, -1]) * 10 ** rng.uniform(-40, 38)) for _ in range(2))
        table = P.Params((("F", P.REAL32, a, a, b), ("I", P.INT32, 0, -2 ** 31, 2 ** 31 - 1),
                          ("U", P.UINT32, 0)))
        for v in (a, b, _f32(rng.uniform(a, b)), _f32(a * 2), _f32(b * 2), -a, -b, 0.0, -0.0):
            assert (table.accept(0, struct.pack("<f", v), 0, False) is None) == (a <= v <= b), (a, b, v)
    table = P.Params((("I", P.INT32, 0, -2 ** 30 - 5, 2 ** 30 + 5), ("U", P.UINT32, 2 ** 31, 2 ** 31, 2 ** 32 - 2)))
    for v in (-2 ** 31, -2 ** 30 - 6, -2 ** 30 - 5, -1, 0, 2 ** 30 + 5, 2 ** 30 + 6, 2 ** 31 - 1):
        assert (table.accept(0, struct.pack("<i", v), 0, False) is None) == (-2 ** 30 - 5 <= v <= 2 ** 30 + 5), v
    for v in (0, 2 ** 31 - 1, 2 ** 31, 3000000000, 2 ** 32 - 2, 2 ** 32 - 1):
        assert (table.accept(1, struct.pack("<I", v), 0, False) is None) == (2 ** 31 <= v <= 2 ** 32 - 2), v
    assert table.accept(1, struct.pack("<I", 2 ** 32 - 1), 0, False) == "out of range 2147483648..4294967294"


def test_negative_zero_is_stored_as_zero():
    table = P.Params((("F", P.REAL32, 1.0, 0.0, 2.0),))
    assert table.accept(0, struct.pack("<f", -0.0), 0, False) is None
    assert bytes(table._values) == bytes(4)


def test_big_values_set_saved_and_reloaded(tmp_path):
    """UINT32 >= 2**30 and INT32 <= -2**30 through PARAM_SET, save and reload."""
    b = Rig(tmp_path, table=MIXED)
    assert raw_value(b.set("U32", as_float("<I", 4000000000), P.UINT32)[0]) == struct.pack("<I", 4000000000)
    assert raw_value(b.set("I32", as_float("<i", -2000000000), P.INT32)[0]) == struct.pack("<i", -2000000000)
    assert [m.result for m in b.command(245, 1) if m.get_type() == "COMMAND_ACK"] == [0]
    b.set("U32", as_float("<I", 3000000000), P.UINT32)
    b.set("I32", as_float("<i", -1500000000), P.INT32)
    assert [m.result for m in b.command(245, 0) if m.get_type() == "COMMAND_ACK"] == [0]
    assert (b.params.get("U32"), b.params.get("I32")) == (4000000000, -2000000000)
    b2 = Rig(tmp_path, table=MIXED)
    assert (b2.params.get("U32"), b2.params.get("I32")) == (4000000000, -2000000000)


# --- application API ----------------------------------------------------------------

def test_application_api(tmp_path):
    b = Rig(tmp_path, links=2)
    i = b.params.index("SIM_SPEED")
    assert b.params.value(i) == 5.0 and b.params.name(i) == "SIM_SPEED" and b.params.type(i) == P.REAL32
    assert b.params.set("SIM_SPEED", 6.5) is True
    assert b.params.set("SIM_SPEED", 6.5) is False
    b.poll(5)
    for link in (0, 1):
        assert [(m.param_id, m.param_value) for m in b.values(link)] == [("SIM_SPEED", 6.5)]
    b.params.set("MAV_SYS_ID", 9)  # read-only for ground stations, not for the application
    assert b.params.get("MAV_SYS_ID") == 9
    for name, value in (("SIM_SPEED", 100.0), ("SIM_GPS_SATS", 2.5), ("SIM_GPS_SATS", 2 ** 31),
                        ("SIM_SPEED", math.nan)):
        with pytest.raises(ValueError):
            b.params.set(name, value)
    with pytest.raises(KeyError):
        b.params.get("NOPE")


# --- persistence --------------------------------------------------------------------

def test_save_and_boot_keep_values(tmp_path):
    b = Rig(tmp_path)
    assert any("defaults" in t for t in b.texts.texts)  # nothing stored yet
    b.set("SIM_SPEED", 9.5, P.REAL32)
    b.set("BATT_CAPACITY", as_float("<i", 4321), P.INT32)
    acks = [m for m in b.command(245, 1) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 0
    b2 = Rig(tmp_path)
    assert b2.params.get("SIM_SPEED") == 9.5 and b2.params.get("BATT_CAPACITY") == 4321
    assert b2.texts.texts == []


def test_reload_and_reset(tmp_path):
    b = Rig(tmp_path, links=2)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    b.command(245, 1)
    b.set("SIM_SPEED", 3.0, P.REAL32)
    b.poll(5)
    b.values(1)
    changes = []
    b.params.on_change = lambda name, value: changes.append((name, value))
    acks = [m for m in b.command(245, 0) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 0 and b.params.get("SIM_SPEED") == 9.5
    b.poll(5)
    assert [(m.param_id, m.param_value) for m in b.values(1)] == [("SIM_SPEED", 9.5)]
    assert changes == [("SIM_SPEED", 9.5)]
    acks = [m for m in b.command(245, 2) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 0 and b.params.get("SIM_SPEED") == 5.0
    assert [m.result for m in b.command(245, 3) if m.get_type() == "COMMAND_ACK"] == [3]
    assert [m.result for m in b.command(245, 7) if m.get_type() == "COMMAND_ACK"] == [2]


def test_reload_without_file_keeps_values(tmp_path):
    b = Rig(tmp_path)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    acks = [m for m in b.command(245, 0) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 4  # FAILED
    assert b.params.get("SIM_SPEED") == 9.5 and "not reloaded" in b.texts.texts[0]


def test_autosave(tmp_path):
    b = Rig(tmp_path, autosave_ms=200)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    b.poll(100)
    assert not b.ep.storage.exists("params")
    b.poll(150)
    assert b.ep.storage.exists("params")
    assert Rig(tmp_path).params.get("SIM_SPEED") == 9.5


def _stored(tmp_path):
    return tmp_path / "storage" / "params"


@pytest.mark.parametrize("damage", ["truncate", "garbage", "empty", "flip", "bad_count"])
def test_corrupt_file_means_defaults_and_next_save_works(tmp_path, damage):
    b = Rig(tmp_path)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    assert b.params.save()
    data = bytearray(_stored(tmp_path).read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "garbage":
        data = bytearray(os.urandom(len(data)))
    elif damage == "empty":
        data = bytearray()
    elif damage == "flip":
        data[len(data) // 2] ^= 0x40
    elif damage == "bad_count":
        data[6] += 1
        struct.pack_into("<H", data, len(data) - 2, crc16(data, 0, len(data) - 2, 0xFFFF))
    _stored(tmp_path).write_bytes(bytes(data))
    b2 = Rig(tmp_path)
    assert b2.params.get("SIM_SPEED") == 5.0
    assert any("corrupt" in t for t in b2.texts.texts)
    b2.set("SIM_SPEED", 11.0, P.REAL32)
    assert b2.params.save()
    assert Rig(tmp_path).params.get("SIM_SPEED") == 11.0


def test_mangled_files_never_raise():
    import random

    table = P.Params(MIXED)
    good = table.pack()
    rng = random.Random(7)
    for _ in range(500):
        data = bytearray(good)
        for _ in range(rng.randint(1, 4)):
            kind = rng.random()
            if not data:
                break
            if kind < 0.4:
                data[rng.randrange(len(data))] = rng.randrange(256)
            elif kind < 0.7:
                del data[rng.randrange(len(data)):]
            else:
                data.insert(rng.randrange(len(data) + 1), rng.randrange(256))
        # A record rewritten with its crc fixed: only the checks behind the crc stop it.
        if rng.random() < 0.5 and len(data) > 10:
            struct.pack_into("<H", data, len(data) - 2, crc16(data, 0, len(data) - 2, 0xFFFF))
        if table.unpack(bytes(data)) >= 0:
            for i in range(table.count):
                assert table.valid(i, table._loaded, 4 * i)


def test_leftover_new_file_never_replaces_the_good_one(tmp_path):
    b = Rig(tmp_path)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    b.params.save()
    (tmp_path / "storage" / "params.new").write_bytes(os.urandom(300))  # a save cut short
    b2 = Rig(tmp_path)
    assert b2.params.get("SIM_SPEED") == 9.5 and b2.texts.texts == []
    assert not (tmp_path / "storage" / "params.new").exists()


def test_failed_write_keeps_previous_file(tmp_path, monkeypatch):
    b = Rig(tmp_path)
    b.set("SIM_SPEED", 9.5, P.REAL32)
    b.params.save()
    good = _stored(tmp_path).read_bytes()
    b.set("SIM_SPEED", 12.0, P.REAL32)

    def full(name, size=None):
        raise OSError(28, "no space")

    monkeypatch.setattr(b.ep.storage, "open_new", full)
    acks = [m for m in b.command(245, 1) if m.get_type() == "COMMAND_ACK"]
    assert acks[0].result == 4 and any("not saved" in t for t in b.texts.texts)
    assert _stored(tmp_path).read_bytes() == good


def test_firmware_update_keeps_remaining_values(tmp_path):
    old = (("KEEP_F", P.REAL32, 1.0, 0.0, 10.0), ("GONE", P.UINT8, 3), ("KEEP_I", P.INT16, 5),
           ("RETYPED", P.UINT8, 1), ("NARROWED", P.REAL32, 5.0, 0.0, 10.0))
    b = Rig(tmp_path, table=old)
    for name, value in (("KEEP_F", 2.5), ("GONE", 4), ("KEEP_I", -7), ("RETYPED", 2), ("NARROWED", 8.0)):
        b.params.set(name, value)
    b.params.save()
    new = (("NEW", P.UINT16, 42), ("KEEP_I", P.INT16, 5), ("RETYPED", P.INT32, 1),
           ("NARROWED", P.REAL32, 5.0, 0.0, 6.0), ("KEEP_F", P.REAL32, 1.0, 0.0, 10.0))
    b2 = Rig(tmp_path, table=new)
    p = b2.params
    assert (p.get("NEW"), p.get("KEEP_I"), p.get("KEEP_F")) == (42, -7, 2.5)
    assert (p.get("RETYPED"), p.get("NARROWED")) == (1, 5.0)  # changed type / now out of range
    assert any("2 stored values invalid" in t for t in b2.texts.texts)


# --- MicroPython: the steady state allocates nothing --------------------------------

_STEADY = "values=%d reads=4 sets=4 commands=2 big=5 refused=461 own=0 " % (N + 1)


@pytest.mark.parametrize("args", [("bytewise", 2, 5760), ("c_cast", 1, 5760), ("bytewise", 1, 200000), ("auto", 2, 5760)])
@pytest.mark.parametrize("portable", [False, True])
def test_steady_state_under_heap_lock(args, portable, monkeypatch):
    """A paced list, reads by index and name, accepted PARAM_SETs and DO_SET_PARAMETERs,
    32-bit values set, saved to RAM storage, changed and reloaded (status, params and
    commands services, in-memory link): nothing asked of the heap (mem_total), then the
    same under heap_lock. own=0: the service's own paths, apart from link and storage.
    refused=461: with the heap locked, refusals are still answered (4 values, 6
    STATUSTEXTs, 1 DENIED)."""
    if portable:
        monkeypatch.setenv("MAVSTACK_PORTABLE", "1")
    r = run_mpy(os.path.join(ROOT, "tests", "mpy", "params_steady.py"), *args,
                path=[os.path.join(ROOT, "tests", "mpy")], timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = [line for line in r.stdout.splitlines() if line.startswith(("ok ", "fail "))]
    assert lines and _STEADY in lines[-1], r.stdout + r.stderr
    assert lines[-1].startswith("ok "), r.stdout  # own paths 0, the locked run and refusals pass
    # The whole steady state (link, parser, encoder, endpoint, commands, status, the
    # in-memory link) asked the heap for nothing either.
    assert " requested=0 " in lines[-1], lines[-1]
