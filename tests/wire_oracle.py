"""pymavlink as the wire-format oracle for the wire-layer tests (CPython side).

Reference modules per dialect and protocol version, random field values (seeded and
hypothesis), frames packed by pymavlink, and the tools shared with tests/mpy/wire_tool.py
to run our parser and encoder over files on either runtime.
"""
import importlib.util
import math
import os
import struct
import subprocess
import sys
import tempfile

from conftest import FIRMWARE, MICROPYTHON, ROOT

MPY_DIR = os.path.join(ROOT, "tests", "mpy")
WIRE_TOOL = os.path.join(MPY_DIR, "wire_tool.py")
for _path in (MPY_DIR, os.path.join(ROOT, "host_tools")):
    if _path not in sys.path:
        sys.path.insert(0, _path)

import mavgen  # noqa: E402  (where the repository's dialects come from)

SPEC_2012 = dict((name, xml) for name, xml, _ in mavgen.committed())["seed2012"]

import wire_tool  # noqa: E402  (runs on both runtimes)

from mavstack.dialects import common as our_common  # noqa: E402
from mavstack.dialects import seed2012 as our_seed2012  # noqa: E402

OURS = {"common": our_common, "seed2012": our_seed2012}

# --- pymavlink reference modules -----------------------------------------------------

_refs = {}
_gen_dir = None


def _import_file(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _generated(xml, wire_protocol, name):
    global _gen_dir
    from pymavlink.generator import mavgen

    if _gen_dir is None:
        _gen_dir = tempfile.mkdtemp(prefix="wire_pymavgen_")
    out = os.path.join(_gen_dir, name + ".py")
    opts = mavgen.Opts(out, wire_protocol=wire_protocol, language="Python3", validate=False)
    assert mavgen.mavgen(opts, [xml])
    return _import_file(name, out)


def reference(dialect, version):
    """pymavlink's module for our dialect name and MAVLink version (1 or 2)."""
    key = (dialect, version)
    if key not in _refs:
        if dialect == "common":
            if version == 2:
                from pymavlink.dialects.v20 import common as mod
            else:
                from pymavlink.dialects.v10 import common as mod
        else:
            wire = "2.0" if version == 2 else "1.0"
            mod = _generated(SPEC_2012, wire, "ref_seed2012_v%d" % version)
        _refs[key] = mod
    return _refs[key]


def classes(dialect, version):
    mod = reference(dialect, version)
    return [mod.mavlink_map[i] for i in sorted(mod.mavlink_map)]


def full_len(dialect, msgid):
    return OURS[dialect].CRC_LEN[msgid] >> 16


def crc_extra(dialect, msgid):
    return OURS[dialect].CRC_LEN[msgid] & 0xFF


# --- field values --------------------------------------------------------------------

INT_RANGES = {
    "uint8_t": (0, 0xFF), "int8_t": (-0x80, 0x7F),
    "uint16_t": (0, 0xFFFF), "int16_t": (-0x8000, 0x7FFF),
    "uint32_t": (0, 0xFFFFFFFF), "int32_t": (-0x80000000, 0x7FFFFFFF),
    "uint64_t": (0, 0xFFFFFFFFFFFFFFFF), "int64_t": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF),
}
CODES = {"uint8_t": "B", "int8_t": "b", "uint16_t": "H", "int16_t": "h", "uint32_t": "I",
         "int32_t": "i", "uint64_t": "Q", "int64_t": "q", "float": "f", "double": "d"}
F32_SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, 3.4028234663852886e38,
               -3.4028234663852886e38, 1.401298464324817e-45, 1.1754943508222875e-38, 1.0, -1.5]
F64_SPECIAL = [math.nan, math.inf, -math.inf, 0.0, -0.0, sys.float_info.max, -sys.float_info.max,
               5e-324, sys.float_info.min, 1.0, -2.5]


def fields(cls):
    """[(name, type, array_length)] in wire order."""
    types = dict(zip(cls.fieldnames, cls.fieldtypes))
    return [(n, types[n], cls.array_lengths[i]) for i, n in enumerate(cls.ordered_fieldnames)]


def _zero(t, n):
    if t == "char":
        return b""
    z = 0.0 if t in ("float", "double") else 0
    return [z] * n if n else z


def _rand_scalar(t, rnd):
    if t == "float":
        if rnd.random() < 0.4:
            return rnd.choice(F32_SPECIAL)
        return struct.unpack("<f", struct.pack("<I", rnd.getrandbits(32)))[0]
    if t == "double":
        if rnd.random() < 0.4:
            return rnd.choice(F64_SPECIAL)
        return struct.unpack("<d", struct.pack("<Q", rnd.getrandbits(64)))[0]
    lo, hi = INT_RANGES[t]
    r = rnd.random()
    if r < 0.15:
        return lo
    if r < 0.3:
        return hi
    if r < 0.4:
        return 0
    return rnd.randint(lo, hi)


def _rand_field(t, n, rnd):
    if t == "char":
        k = n if rnd.random() < 0.5 else rnd.randint(0, n)
        return rnd.randbytes(k)
    if n:
        return [_rand_scalar(t, rnd) for _ in range(n)]
    return _rand_scalar(t, rnd)


def random_values(cls, rnd):
    """{field: value} with extremes, NaN/inf, full-length strings and arrays, and often a
    zero tail (so that MAVLink 2 truncation has something to trim)."""
    spec = fields(cls)
    r = rnd.random()
    if r < 0.05:
        cut = 0  # all zero: the frame still carries one payload byte
    elif r < 0.4:
        cut = rnd.randint(0, len(spec))
    else:
        cut = len(spec)
    values = {}
    for i, (name, t, n) in enumerate(spec):
        if i >= cut or rnd.random() < 0.1:
            values[name] = _zero(t, n)
        else:
            values[name] = _rand_field(t, n, rnd)
    return values


def values_strategy(cls):
    """The same kind of values as a hypothesis strategy."""
    from hypothesis import strategies as st

    def scalar(t):
        if t == "float":
            return st.floats(width=32)
        if t == "double":
            return st.floats()
        lo, hi = INT_RANGES[t]
        return st.one_of(st.sampled_from([lo, hi, 0]), st.integers(lo, hi))

    def field(t, n):
        if t == "char":
            return st.one_of(st.binary(min_size=n, max_size=n), st.binary(max_size=n))
        if not n:
            return scalar(t)
        code = CODES[t]
        size = struct.calcsize("<" + code)
        # One draw per array keeps examples small: raw bits, plus a few specials.
        raw = st.binary(min_size=n * size, max_size=n * size).map(
            lambda b, c=code, k=n: list(struct.unpack("<%d%s" % (k, c), b)))
        return st.one_of(raw, st.lists(scalar(t), min_size=n, max_size=n))

    spec = fields(cls)

    @st.composite
    def build(draw):
        cut = draw(st.integers(0, len(spec)))
        return {name: (draw(field(t, n)) if i < cut else _zero(t, n))
                for i, (name, t, n) in enumerate(spec)}

    return build()


def make(cls, values):
    return cls(*[values[n] for n in cls.fieldnames])


def flat(cls, values):
    """Values in wire order, arrays flattened: the arguments for struct.pack(FMT, ...)."""
    out = []
    for name, t, n in fields(cls):
        v = values[name]
        if t != "char" and n:
            out.extend(v)
        else:
            out.append(v)
    return out


def has_nan(values):
    for v in values.values():
        for x in (v if isinstance(v, list) else [v]):
            if isinstance(x, float) and math.isnan(x):
                return True
    return False


def same(a, b):
    """Equal values, NaN equal to NaN, -0.0 distinct from 0.0; bytes compared up to NUL padding."""
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b and math.copysign(1, a) == math.copysign(1, b)
    if isinstance(a, bytes) and isinstance(b, bytes):
        return a.rstrip(b"\0") == b.rstrip(b"\0")
    return a == b


class _Sink:
    def write(self, b):
        pass


def mav(dialect, version, sysid=1, compid=1, seq=0, sign_key=None):
    """A pymavlink MAVLink object (no file) for packing and decoding."""
    m = reference(dialect, version).MAVLink(_Sink(), sysid, compid)
    m.seq = seq
    m.robust_parsing = True
    if sign_key is not None:
        m.signing.secret_key = sign_key
        m.signing.sign_outgoing = True
        m.signing.link_id = 3
        m.signing.timestamp = 123456
    return m


def pack(dialect, version, cls, values, seq=0, sysid=1, compid=1, sign_key=None):
    """pymavlink's frame for a message."""
    return make(cls, values).pack(mav(dialect, version, sysid, compid, seq, sign_key))


def decode_frames(dialect, version, data):
    """pymavlink's messages (bad data included) for a byte string of frames."""
    m = mav(dialect, version)
    return m.parse_buffer(bytes(data)) or []


def x25(data, extra=None):
    crc = 0xFFFF
    for b in bytes(data) + (bytes([extra]) if extra is not None else b""):
        t = (b ^ crc) & 0xFF
        t = (t ^ (t << 4)) & 0xFF
        crc = ((crc >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return crc


def frame(version, msgid, payload, crc_extra_byte, seq=0, sysid=1, compid=1, iflags=0,
          signature=None, length=None):
    """A hand-made frame: any length byte, flags and signature, CRC computed correctly."""
    plen = len(payload) if length is None else length
    if version == 2:
        if signature is not None:
            iflags |= 1
        head = bytes([0xFD, plen, iflags, 0, seq, sysid, compid,
                      msgid & 0xFF, (msgid >> 8) & 0xFF, msgid >> 16])
    else:
        head = bytes([0xFE, plen, seq, sysid, compid, msgid])
    body = head + bytes(payload)
    crc = x25(body[1:], crc_extra_byte)
    out = body + bytes([crc & 0xFF, crc >> 8])
    if signature is not None:
        out += bytes(signature)
    return out


# --- running the wire tool -----------------------------------------------------------


def run_tool(args, portable=False, runtime="mpy", timeout=120):
    """wire_tool.py under MicroPython (viper unless portable) or in-process on CPython."""
    if runtime == "cpython":
        return wire_tool.main([str(a) for a in args])
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join([MPY_DIR, FIRMWARE, ".frozen"])
    env.pop("MAVSTACK_PORTABLE", None)
    if portable:
        env["MAVSTACK_PORTABLE"] = "1"
    p = subprocess.run([MICROPYTHON, "-X", "heapsize=64M", WIRE_TOOL] + [str(a) for a in args],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, p.stdout + p.stderr
    return p.stdout


RUNTIMES = [("mpy", False), ("mpy", True), ("cpython", True)]
RUNTIME_IDS = ["mpy-viper", "mpy-portable", "cpython"]


def parse_files(dialect, paths, chunks, out, runtime="mpy", portable=False):
    """Parse each stream file with a fresh Parser -> [(frames, stats)] and the kernel set used."""
    impl = run_tool(["parse", dialect, chunks, out] + list(paths), portable, runtime)
    return read_parsed(out), impl.strip()


def read_parsed(path):
    """wire_tool parse output -> [([frame dict], stats dict)], one per input stream."""
    results = []
    frames = None
    with open(path) as f:
        for line in f:
            w = line.split()
            if w[0] == "B":
                frames = []
            elif w[0] == "F":
                frames.append({
                    "version": int(w[1]), "msgid": int(w[2]), "seq": int(w[3]),
                    "sysid": int(w[4]), "compid": int(w[5]), "signed": w[6] == "1",
                    "wire": bytes.fromhex(w[7]), "payload": bytes.fromhex(w[8]),
                    "signature": b"" if w[9] == "-" else bytes.fromhex(w[9]),
                })
            elif w[0] == "S":
                keys = wire_tool.STATS + ("pending",)
                results.append((frames, dict(zip(keys, map(int, w[1:])))))
    return results


def strip_crc(raw):
    """A frame's bytes without its CRC: what a delivered frame can be compared on."""
    hdr = 10 if raw[0] == 0xFD else 6
    end = hdr + raw[1]
    return raw[:end], raw[end + 2:]


# --- streams of random frames ---------------------------------------------------------


def random_message(rnd, dialect, version):
    cls = rnd.choice(classes(dialect, version))
    return cls, random_values(cls, rnd)


def random_frames(rnd, n, dialect="common", v1_share=0.3, signed_share=0.2):
    """n random pymavlink frames, mixed MAVLink 1, 2 and signed 2."""
    out = []
    for _ in range(n):
        version = 1 if rnd.random() < v1_share else 2
        cls, values = random_message(rnd, dialect, version)
        key = bytes(range(32)) if version == 2 and rnd.random() < signed_share else None
        out.append(pack(dialect, version, cls, values, seq=rnd.getrandbits(8),
                        sysid=rnd.getrandbits(8), compid=rnd.getrandbits(8), sign_key=key))
    return out


def garbage(rnd, dialect="common"):
    """Bytes between frames: noise, bare start markers, or a fake header whose length
    swallows what follows."""
    kind = rnd.random()
    if kind < 0.4:
        return rnd.randbytes(rnd.randint(1, 40))
    if kind < 0.6:
        return bytes(rnd.choice([0xFD, 0xFE, 0x00, 0x55]) for _ in range(rnd.randint(1, 6)))
    ids = sorted(OURS[dialect].CRC_LEN)
    msgid = rnd.choice(ids)
    if kind < 0.8:
        return bytes([0xFD, rnd.randint(1, full_len(dialect, msgid)), rnd.choice([0, 0, 1]), 0,
                      1, 1, 1, msgid & 0xFF, (msgid >> 8) & 0xFF, msgid >> 16])
    v1 = [i for i in ids if i < 256]
    msgid = rnd.choice(v1)
    return bytes([0xFE, (OURS[dialect].CRC_LEN[msgid] >> 8) & 0xFF, 0, 1, 1, msgid])


def corrupt(rnd, frames, rate=0.15, garbage_rate=0.15, dialect="common"):
    """Insert, delete and flip bytes in a stream of frames.

    Returns (stream, intact): the indices of the frames whose bytes are still all there,
    unchanged and contiguous. Signatures are left alone: they are outside the CRC, so
    damage there is for the signing layer (not the parser) to notice.
    """
    out = bytearray()
    intact = []
    for i, f in enumerate(frames):
        if rnd.random() < garbage_rate:
            out += garbage(rnd, dialect)
        if rnd.random() >= rate:
            out += f
            intact.append(i)
            continue
        covered = (10 if f[0] == 0xFD else 6) + f[1] + 2  # header, payload, CRC
        region, signature = bytearray(f[:covered]), f[covered:]
        for _ in range(rnd.randint(1, 3)):
            op = rnd.random()
            if op < 0.4 or len(region) < 3:
                region[rnd.randrange(len(region))] ^= rnd.randint(1, 255)
            elif op < 0.7:
                at = rnd.randrange(len(region) - 1)
                del region[at:at + rnd.randint(1, 3)]
            else:
                at = rnd.randrange(1, len(region))  # strictly inside the frame
                region[at:at] = garbage(rnd, dialect) if rnd.random() < 0.5 else bytes([rnd.getrandbits(8)])
        # Edits can cancel out or rebuild the frame a byte further on (flip the start
        # marker, then insert a new one after it): then it is there intact.
        original = f[:covered]
        if region.endswith(original) or (not signature and original in region):
            intact.append(i)
        out += region + signature
    return bytes(out), intact


class MemoryTransport:
    """In-process byte pipe: what a peer sent in `rx`, what the link wrote in `tx`."""

    name = "memory"
    bytes_per_s = 100000

    def __init__(self, accept=True):
        self.rx = bytearray()
        self.tx = bytearray()
        self.accept = accept

    def readinto(self, buf):
        n = min(len(buf), len(self.rx))
        buf[:n] = self.rx[:n]
        del self.rx[:n]
        return n

    def write(self, buf, n):
        if not self.accept:
            return 0
        self.tx += buf[:n]
        return n

    def close(self):
        pass
