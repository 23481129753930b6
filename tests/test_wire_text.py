"""No wire text can raise. fields.cstr_text turns a char[] field into text the same way on
MicroPython and CPython (ill-formed UTF-8 replaced, as CPython's errors="replace"); the
simulator's debug handler takes such a name under MicroPython; and the unix vehicle (with
its simulator) is sent ill-formed UTF-8 in every char[] field of its dialect and in FTP
paths, in today's message set and in the seed's: it stays up, answers, refuses by the
protocol where the protocol has an answer, counts no fault and prints no traceback."""
import os
import random
import socket
import struct
import time

from conftest import ROOT, recv, run_mpy
from gcs_tools import statustext
from mavctl_tools import signed_board

# Ill-formed UTF-8 of every kind: bytes no sequence starts with, a stray continuation, a
# truncated character, overlong forms (of "." and "/"), a surrogate, past U+10FFFF.
BAD = [b"\xff\xfe\xc3abc", b"\xff" * 250, b"ok\xe2\x82", b"\x80name", b"\xc0\xae\xc0\xae",
       b"\xc0\xaf\xed\xa0\x80", b"\xf4\x90\x80\x80", b"\xf0\x9f\x98"]
FFFD = "\ufffd"
PASSKEY = "pw"


# --- the helper, on both runtimes -------------------------------------------------------
def _cases():
    fixed = [b"", b"plain", b"caf\xc3\xa9", b"\xe2\x82\xac\xf0\x9f\x98\x80", b"a\x00\xff", b"\x00\xff",
             b"\xff" * 16, b"\xe2\x82", b"\xe2\x82a", b"\xf0\x9f\x98", b"\xc3", b"\xef\xbf\xbd"] + BAD
    r = random.Random(20)
    near = [0, 0x41, 0x7F, 0x80, 0x8F, 0x90, 0x9F, 0xA0, 0xBF, 0xC0, 0xC1, 0xC2, 0xDF, 0xE0, 0xE1, 0xED,
            0xEE, 0xEF, 0xF0, 0xF1, 0xF4, 0xF5, 0xFF]
    rand = [bytes(r.choice(near) if r.random() < 0.7 else r.randrange(256) for _ in range(r.randrange(1, 14)))
            for _ in range(400)]
    return fixed + rand


MPY_CASES = r"""
import sys
from mavstack.fields import cstr_text
with open(sys.argv[1]) as f:  # (a file: the unix port takes no argument of 256 bytes or more)
    cases = [bytes.fromhex(h) for h in f.read().split(",")]
for c in cases:
    n = len(c)
    padded = bytearray(b"xy" + c + bytes(3))
    for s in (cstr_text(c, 0, n), cstr_text(bytearray(c), 0, n), cstr_text(memoryview(padded), 2, n)):
        print("=" + s.encode().hex())
"""


def test_cstr_text_the_same_on_micropython_and_cpython(tmp_path):
    from mavstack.fields import cstr_text

    cases = _cases()
    want = [c.split(b"\0")[0].decode("utf-8", "replace") for c in cases]
    for c, w in zip(cases, want):  # CPython: bytes, bytearray, a view at an offset
        padded = bytearray(b"xy" + c + bytes(3))
        assert cstr_text(c, 0, len(c)) == w
        assert cstr_text(bytearray(c), 0, len(c)) == w
        assert cstr_text(memoryview(padded), 2, len(c)) == w
    assert cstr_text(b"\xff\xfe\xc3abc", 0, 6) == FFFD * 3 + "abc"
    assert cstr_text(b"abcdef", 1, 3) == "bcd"  # n bytes at most, no NUL needed
    (tmp_path / "cases").write_text(",".join(c.hex() for c in cases))
    r = run_mpy(MPY_CASES, tmp_path / "cases")
    assert r.returncode == 0, r.stdout + r.stderr
    got = [line[1:] for line in r.stdout.split()]
    assert len(got) == 3 * len(cases), r.stdout[-500:]
    for i, w in enumerate(want):
        for k in range(3):
            assert bytes.fromhex(got[3 * i + k]).decode() == w, cases[i]


MPY_QUEUE = r"""
from mavstack.statustext import TextQueue
q = TextQueue(2)
q.put(6, "x" * 48 + "\u20ac")            # 51 bytes: the euro sign would be cut inside
q.put(6, b"\xff\xfe\xc3abc")             # bytes as given
print(len(q.buf[q.head * 51 + 1:q.head * 51 + 51].split(b"\0")[0]), q.text(0) == "x" * 48, q.text(1).encode().hex())
"""


def test_statustext_cut_before_a_character_and_read_back_without_raising():
    r = run_mpy(MPY_QUEUE)
    assert r.returncode == 0, r.stdout + r.stderr
    n, cut, last = r.stdout.split()
    assert (n, cut) == ("48", "True")
    assert bytes.fromhex(last).decode() == FFFD * 3 + "abc"
    from mavstack.statustext import TextQueue

    q = TextQueue(2)
    q.put(6, "x" * 48 + "\u20ac")
    q.put(6, b"\xff\xfe\xc3abc")
    assert q.text(0) == "x" * 48 and q.text(1) == FFFD * 3 + "abc"


MPY_DEBUG = r"""
from harness import Bench
from sim import seed

b = Bench(services=("status", "debug"))
seed.compose(b.ep)
texts = []
b.watch = lambda msgid, p: texts.append(bytes(p[1:51]).split(b"\0")[0]) if msgid == 253 else None
g = b.gcs()
b.send(g.heartbeat())
for name in (b"\xff\xfe\xc3abc", b"\xff" * 10, b"ok\xe2\x82", b"\xc0\xae\xed\xa0\x80"):
    b.send(g.frame(251, 0, 1.5, name))
    b.send(g.frame(252, 0, -7, name))
    b.send(g.frame(250, 0, 1.0, 2.0, 3.0, name))
    b.run(40)
print("faults", sum(b.ep.faults.counts))
print("values", len(b.ep.services["debug"].values))
for t in texts:
    if t.startswith(b"Debug"):
        print("text", t.hex())
"""


def test_simulator_debug_names_on_micropython():
    r = run_mpy(MPY_DEBUG, path=[os.path.join(ROOT, "tests", "mpy")])
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert "faults 0" in lines, r.stdout
    assert "values 4" in lines, r.stdout  # one name for all three messages of each round
    texts = [bytes.fromhex(x.split()[1]).decode() for x in lines if x.startswith("text ")]
    assert "Debug %sabc=1.50" % (FFFD * 3) in texts, texts
    assert "Debug %s=-7" % (FFFD * 10) in texts, texts
    assert "Debug ok%s=(1.00,2.00,3.00)" % FFFD in texts, texts
    assert "Debug %s=1.50" % (FFFD * 5) in texts, texts  # overlong ".", then a surrogate


# --- the vehicle --------------------------------------------------------------------------
class Station:
    """A ground station of a pymavlink module (today's or the seed's) on a UDP socket:
    frames of any message, the answers read as they come."""

    def __init__(self, mod, port):
        self.mod = mod
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(0.05)
        self.addr = ("127.0.0.1", port)
        self.mav = mod.MAVLink(None, srcSystem=255, srcComponent=190)
        self.mav.robust_parsing = True
        self.texts = []  # every STATUSTEXT heard
        self.not_utf8 = []  # and any that was not UTF-8
        self.faults = []  # SYS_STATUS errors_count2..4 as last heard

    def close(self):
        self.sock.close()

    def send(self, msg):
        self.sock.sendto(msg.pack(self.mav), self.addr)

    def message(self, msgid, texts, **given):
        """Message msgid with every char[] field set from texts (bytes, cut to the field),
        the targets 1/1, the rest zero (or as given)."""
        cls = self.mod.mavlink_map[msgid]
        assert set(given) <= set(cls.fieldnames), (cls.fieldnames, given)
        args = []
        for i, (name, kind) in enumerate(zip(cls.fieldnames, cls.fieldtypes)):
            n = cls.array_lengths[cls.orders[i]]
            if name in given:
                args.append(given[name])
            elif kind == "char":
                args.append(texts[:n] if n else texts[:1])
            elif name in ("target_system", "target_component", "target"):
                args.append(1)
            elif n:
                args.append([0] * n)
            else:
                args.append(0.0 if kind in ("float", "double") else 0)
        return cls(*args)

    def frames(self, wait):
        got = []
        deadline = time.time() + wait
        while time.time() < deadline:
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            for m in self.mav.parse_buffer(data) or []:
                if m.get_type() == "STATUSTEXT":  # as sent, UTF-8 (pymavlink reads it as ASCII)
                    raw = bytes(m._text_raw).split(b"\0")[0]
                    try:
                        self.texts.append(raw.decode())
                    except UnicodeError:
                        self.not_utf8.append(raw)
                elif m.get_type() == "SYS_STATUS":
                    self.faults = [m.errors_count2, m.errors_count3, m.errors_count4]
                got.append(m)
        return got

    def answer(self, msg, kinds, cond=None, tries=4, wait=1.0):
        """Send msg until a message of one of kinds (matching cond) comes -> it, or None."""
        for _ in range(tries):
            self.send(msg)
            deadline = time.time() + wait
            while time.time() < deadline:
                for m in self.frames(0.1):
                    if m.get_type() in kinds and (cond is None or cond(m)):
                        return m
        return None

    def alive(self):
        """The vehicle answers a PARAM_REQUEST_READ of MAV_SYS_ID."""
        p = self.answer(self.message(20, b"MAV_SYS_ID", param_index=-1), ("PARAM_VALUE",),
                        lambda p: p.param_id == "MAV_SYS_ID")
        assert p is not None, "the vehicle stopped answering"
        return p

    def no_faults(self, v):
        v.check_alive()
        deadline = time.time() + 5
        self.faults = None
        while self.faults is None and time.time() < deadline:
            self.frames(0.2)
        assert self.faults == [0, 0, 0], self.faults
        assert not [t for t in self.texts if "Fault" in t], self.texts
        assert not self.not_utf8


def _text_messages(mod):
    """Ids of the module's messages with a char[] field."""
    return sorted(i for i, cls in mod.mavlink_map.items() if "char" in cls.fieldtypes)


def _stopped_clean(v):
    v.stop()
    out = v.output()
    assert "Traceback" not in out and "Fault" not in out, out


def _every_text_field(g, v, dialect):
    """Every message of the dialect with a char[] field, with each BAD text in all of them."""
    ids = _text_messages(g.mod)
    theirs = __import__("mavstack.dialects." + dialect, None, None, ("FMT",)).FMT
    assert {i for i, fmt in theirs.items() if "s" in fmt} <= set(ids)  # every one the vehicle knows
    for bad in BAD:
        for msgid in ids:
            g.send(g.message(msgid, bad))
        g.frames(0.1)
        v.check_alive()
        g.alive()
    return ids


def _ftp_request(g, opcode, path, seq):
    payload = struct.pack("<HBBBBBBI", seq, 0, opcode, len(path), 0, 0, 0, 0) + path
    return g.message(110, b"", payload=list(payload.ljust(251, b"\0")), target_network=0)


def test_common_dialect(vehicle, tmp_path):
    from pymavlink.dialects.v20 import common

    storage = tmp_path / "storage"
    storage.mkdir()
    (storage / "hello.txt").write_bytes(b"hello")
    v = vehicle(storage=storage, args=["--set", "operator_passkey=" + PASSKEY])
    g = Station(common, v.port)
    try:
        g.send(g.message(0, b"", type=6, autopilot=8, mavlink_version=3))
        g.alive()
        # CHANGE_OPERATOR_CONTROL: a passkey that is not UTF-8 is a wrong passkey.
        for bad in BAD:
            a = g.answer(g.message(5, bad, control_request=0, version=0), ("CHANGE_OPERATOR_CONTROL_ACK",))
            assert a is not None and a.ack == 1, bad  # NACK: wrong passkey
        a = g.answer(g.message(5, PASSKEY.encode(), control_request=0, version=0), ("CHANGE_OPERATOR_CONTROL_ACK",))
        assert a.ack == 0
        # PARAM_REQUEST_READ / PARAM_SET of names that are not UTF-8: PARAM_ERROR
        # DOES_NOT_EXIST, the name echoed as sent, and no PARAM_VALUE.
        for bad in BAD + [b"MAV_SYS_ID\xff"]:
            for msg in (g.message(20, bad, param_index=-1), g.message(23, bad, param_value=1.0, param_type=9)):
                e = g.answer(msg, ("PARAM_ERROR", "PARAM_VALUE"), lambda m: m.get_type() == "PARAM_ERROR"
                             or m.param_id != "MAV_SYS_ID")
                assert e is not None and e.get_type() == "PARAM_ERROR", (bad, e)
                assert e.error == 1 and e.param_index == -1
        # NAMED_VALUE_FLOAT / _INT, DEBUG_VECT: the simulator says them, U+FFFD for what is not UTF-8.
        g.send(g.message(251, b"\xff\xfe\xc3abc", value=1.5))
        g.send(g.message(252, b"\xff" * 10, value=-7))
        g.send(g.message(250, b"ok\xe2\x82", x=1.0, y=2.0, z=3.0))
        deadline = time.time() + 5
        want = {"Debug %sabc=1.50" % (FFFD * 3), "Debug %s=-7" % (FFFD * 10), "Debug ok%s=(1.00,2.00,3.00)" % FFFD}
        while not want <= set(g.texts) and time.time() < deadline:
            g.frames(0.2)
        assert want <= set(g.texts), [t for t in g.texts if "Debug" in t]
        # AUTH_KEY over this unsigned link: refused before its key is read.
        g.send(g.message(7, b"\xff" * 32))
        assert statustext_in(g, "AUTH_KEY refused: link not signed")
        _ftp_paths(g, storage)
        _every_text_field(g, v, "common")
        g.no_faults(v)
    finally:
        g.close()
    _stopped_clean(v)


def _ftp_paths(g, storage):
    """FTP List / OpenFileRO / CalcFileCRC32 / CreateFile / RemoveFile of paths that are not
    UTF-8: NAK FAIL each, and nothing created or removed."""
    before = sorted(os.listdir(storage))
    seq = 500
    for bad in BAD[:1] + BAD[2:] + [b"hello\xff.txt", b"/\xc0\xae\xc0\xae/hello.txt", b"new\xed\xa0\x80.txt"]:
        for opcode in (3, 4, 14, 6, 8):  # List, OpenFileRO, CalcFileCRC32, CreateFile, RemoveFile
            seq += 2
            r = g.answer(_ftp_request(g, opcode, bad[:239], seq), ("FILE_TRANSFER_PROTOCOL",),
                         lambda m, s=seq: struct.unpack("<H", bytes(m.payload[0:2]))[0] == s + 1)
            assert r is not None, (bad, opcode)
            p = bytes(r.payload)
            assert p[3] == 129 and p[12] == 1, (bad, opcode, p[:14])  # NAK FAIL
    assert sorted(os.listdir(storage)) == before
    # The folder still served: the file there is read.
    seq += 2
    r = g.answer(_ftp_request(g, 4, b"/hello.txt", seq), ("FILE_TRANSFER_PROTOCOL",),
                 lambda m: struct.unpack("<H", bytes(m.payload[0:2]))[0] == seq + 1)
    assert bytes(r.payload)[3] == 128  # ACK
    g.send(_ftp_request(g, 2, b"", seq + 2))  # ResetSessions


def test_seed_dialect(vehicle, seedmav, tmp_path):
    storage = tmp_path / "storage"
    storage.mkdir()
    (storage / "hello.txt").write_bytes(b"hello")
    v = vehicle(storage=storage, args=["--set", "dialect=seed2012", "--set", "operator_passkey=" + PASSKEY])
    g = Station(seedmav, v.port)
    try:
        g.send(g.message(0, b"", type=6, autopilot=8, mavlink_version=3))
        g.alive()
        for bad in BAD:
            a = g.answer(g.message(5, bad, control_request=0, version=0), ("CHANGE_OPERATOR_CONTROL_ACK",))
            assert a is not None and a.ack == 1, bad
        a = g.answer(g.message(5, PASSKEY.encode(), control_request=0, version=0), ("CHANGE_OPERATOR_CONTROL_ACK",))
        assert a.ack == 0
        # The seed has no PARAM_ERROR: a name that is not UTF-8 gets no PARAM_VALUE.
        for bad in BAD + [b"MAV_SYS_ID\xff"]:
            g.send(g.message(20, bad, param_index=-1))
            g.send(g.message(23, bad, param_value=1.0, param_type=9))
        assert not [m for m in g.frames(1.0) if m.get_type() == "PARAM_VALUE" and m.param_id != "MAV_SYS_ID"]
        g.alive()
        # FILE_TRANSFER_DIR_LIST / _START (read, write) of paths that are not UTF-8: result 2
        # (bad path), nothing written.
        before = sorted(os.listdir(storage))
        uid = 7000
        for bad in BAD + [b"hello\xff.txt", b"\xc0\xae\xc0\xae/hello.txt"]:
            # The station in control keeps sending its HEARTBEAT, as a ground station does
            # (control lapses GCS_TIMEOUT_MS after the last: the writes would be refused).
            g.send(g.message(0, b"", type=6, autopilot=8, mavlink_version=3))
            for msgid, given in ((111, {}), (110, {"direction": 1}), (110, {"direction": 0, "file_size": 5})):
                uid += 1
                msg = g.message(msgid, bad[:240], transfer_uid=uid, **given)
                r = g.answer(msg, ("FILE_TRANSFER_RES",), lambda m, u=uid: m.transfer_uid == u)
                assert r is not None and r.result == 2, (bad, msg.get_type(), r)
        assert sorted(os.listdir(storage)) == before
        g.send(g.message(251, b"\xff\xfe\xc3abc", value=1.5))
        assert statustext_in(g, "Debug %sabc=1.50" % (FFFD * 3))
        _every_text_field(g, v, "seed2012")
        g.no_faults(v)
    finally:
        g.close()
    _stopped_clean(v)


def statustext_in(g, text, timeout=5.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        if text in g.texts:
            return True
        g.frames(0.2)
    return False


def test_auth_key_over_a_signed_link(vehicle, tmp_path):
    # The key is read (and compared) only in a signed frame: sent so, a key that is not UTF-8.
    v = vehicle(board="unix_signed", env={"MICROPYPATH": signed_board(tmp_path)})
    m = v.gcs()
    key = bytes(range(1, 33))
    stamp = int((time.time() - 1420070400) * 1e5)
    m.mav.setup_signing_send(1, 1, key, stamp)
    m.setup_signing(key, sign_outgoing=True, initial_timestamp=stamp + 100)
    for bad in BAD:
        m.mav.auth_key_send(bad[:32])
        assert statustext(m, "AUTH_KEY accepted") is not None, bad
    m.mav.param_request_read_send(1, 1, b"MAV_SYS_ID", -1)
    assert recv(m, "PARAM_VALUE", 5, lambda p: p.param_id == "MAV_SYS_ID") is not None
    s = recv(m, "SYS_STATUS", 5)
    assert (s.errors_count2, s.errors_count3, s.errors_count4) == (0, 0, 0)
    _stopped_clean(v)
