"""The fuzzer's side of the vehicle's udpin link: a UDP port per speaker (the fuzz, the
well-behaved ground station), datagrams sized so that the vehicle reads each one whole,
the sentinel that tells when the vehicle has handled every byte sent before it, signing
timestamps, and a light reader of what the vehicle sends (it decodes only what is asked).

MicroPython's UDP readinto fills its buffer with as many queued datagrams as fit and
cuts the one that does not (transport/udp.py): datagrams of exactly the vehicle's
rx_chunk (4096 bytes, zero padded) are read one whole datagram at a time.
"""
import socket
import struct
import time

from fuzz import frames

DATAGRAM = 4096  # the unix vehicle's UDP rx_chunk (transport/udp.py)
PAD = bytes(300)  # finishes any frame a batch left half sent (a longer frame than any)
CMD_BASE = 60000  # sentinel k is COMMAND_LONG with command CMD_BASE + k: none of MAVLink's
_SENTINELS = 1000
_MSG_COMMAND_LONG = 76
_MSG_COMMAND_ACK = 77


class Port:
    """One UDP socket connected to the vehicle's udpin port: a peer once it sent a frame."""

    def __init__(self, port):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.connect(("127.0.0.1", port))
        self.sock.setblocking(False)

    def send(self, data):
        """-> False when the vehicle's port is closed (it is restarting)."""
        try:
            self.sock.send(data)
            return True
        except OSError:
            return False

    def received(self, wait=0.0):
        """Datagrams waiting (after waiting up to `wait` s for the first) -> list."""
        out = []
        deadline = time.time() + wait
        while True:
            try:
                out.append(self.sock.recv(65536))
            except BlockingIOError:
                if out or time.time() >= deadline:
                    return out
                time.sleep(0.0002)
            except OSError:  # the vehicle's port closed (a reboot): nothing to read
                return out

    def close(self):
        self.sock.close()


def pack(chunks, size=DATAGRAM):
    """Byte strings (each at most size) -> datagrams of exactly size bytes, none split."""
    out = []
    cur = bytearray()
    for c in chunks:
        if len(cur) + len(c) > size:
            out.append(bytes(cur.ljust(size, b"\0")))
            cur = bytearray()
        cur += c
    if cur:
        out.append(bytes(cur.ljust(size, b"\0")))
    return out


def split(data, size=DATAGRAM - len(PAD)):
    """Raw bytes -> pieces of at most size bytes."""
    return [data[i:i + size] for i in range(0, len(data), size)]


class Signing:
    """The key in force as the fuzzer knows it (from the vehicle's storage), and the
    vehicle's clock as its signed frames show it."""

    def __init__(self):
        self.key = None  # the key in force (None: signing off)
        self.seen = 0  # the newest timestamp of the vehicle's own frames

    def saw(self, f):
        if f[0] == 0xFD and f[2] & 1 and len(f) >= 25:
            ts = int.from_bytes(f[-12:-6], "little")
            if ts > self.seen:
                self.seen = ts


class Speaker:
    """Frames from one identity (sysid, compid) of a dialect: numbered, and signed when a
    key is in force, each timestamp above its last and above the vehicle's clock, as a
    ground station's are."""

    def __init__(self, ident, table, signing):
        self.sysid, self.compid = ident
        self.table = table
        self.signing = signing
        self.seq = 0
        self.last = 0  # the last timestamp signed with

    def stamp(self):
        self.last = max(self.last + 1, self.signing.seen + 1)
        return self.last

    def frame(self, name_or_id, key=False, stamp=None, **fields):
        """A frame of this message (a name or an id) with these fields; signed with the key
        in force on this speaker's stream, or with `key` (None: unsigned) at `stamp` on
        a stream of its own (link id 1: what it is accepted at leaves the first alone)."""
        msgid = name_or_id if isinstance(name_or_id, int) else ids(self.table)[name_or_id]
        lay = self.table[msgid]
        p = bytearray(lay.len2)
        for name, value in fields.items():
            f = lay.fields.get(name)
            if f is not None and f[2] and f[1] != "char":  # an array: element by element
                for k, v in enumerate(value):
                    frames.put(p, lay, name, v, k)
            else:
                frames.put(p, lay, name, value)
        self.seq += 1
        if key is False:
            key = self.signing.key
        link_id = 0 if stamp is None else 1
        if key is None:
            stamp = 0
        elif stamp is None:
            stamp = self.stamp()
        return frames.encode(msgid, p, self.sysid, self.compid, self.seq, 2, key, link_id, stamp, self.table)


_IDS = {}


def ids(table):
    """{message name: id} of a layouts table."""
    if id(table) not in _IDS:
        _IDS[id(table)] = {lay.name: msgid for msgid, lay in table.items()}
    return _IDS[id(table)]


class Sentinel:
    """COMMAND_LONGs of an id no command has, from frames.SENTINEL: the vehicle answers each
    with a COMMAND_ACK naming it once every byte before it is handled."""

    def __init__(self, table, signing):
        self.speaker = Speaker(frames.SENTINEL, table, signing)
        self.k = 0

    def next(self, key=False, stamp=None):
        """-> (its command id, the frame); signed as Speaker.frame says."""
        self.k = (self.k + 1) % _SENTINELS
        cmd = CMD_BASE + self.k
        return cmd, self.speaker.frame(_MSG_COMMAND_LONG, key, stamp, command=cmd, target_system=1,
                                       target_component=1)


def setup_signing(chunks):
    """(key, initial timestamp) of the last SETUP_SIGNING frame that starts a chunk, else
    None: the key a batch may have put in force (a sentinel signed with it follows)."""
    found = None
    for c in chunks:
        if len(c) > 10 and c[0] == 0xFD and c[7] == 0 and c[8] == 1 and c[9] == 0:
            p = bytes(c[10:10 + c[1]]).ljust(42, b"\0")
            found = (p[10:42], int.from_bytes(p[0:6], "little"))
    return found


def scan(datagram):
    """-> [(msgid, sysid, compid, payload, frame)] of the MAVLink frames in a datagram the
    vehicle sent (one a datagram; no CRC check: loopback does not corrupt)."""
    out = []
    o = 0
    n = len(datagram)
    while o < n:
        stx = datagram[o]
        if stx == 0xFD and o + 12 <= n:
            plen = datagram[o + 1]
            end = o + 12 + plen + (13 if datagram[o + 2] & 1 else 0)
            msgid = datagram[o + 7] | datagram[o + 8] << 8 | datagram[o + 9] << 16
            out.append((msgid, datagram[o + 5], datagram[o + 6], datagram[o + 10:o + 10 + plen], datagram[o:end]))
            o = end
        elif stx == 0xFE and o + 8 <= n:
            plen = datagram[o + 1]
            end = o + 8 + plen
            out.append((datagram[o + 5], datagram[o + 3], datagram[o + 4], datagram[o + 6:o + 6 + plen],
                        datagram[o:end]))
            o = end
        else:
            o += 1
    return out


def decode(table, msgid, payload):
    """The fields of a payload by name (MAVLink 2's trimmed zeros put back)."""
    lay = table.get(msgid)
    if lay is None:
        return None
    values = struct.unpack_from(lay.fmt, bytes(payload[:lay.len2]).ljust(lay.len2, b"\0"))
    out = {}
    k = 0
    for name, ctype, count, _ in sorted(lay.fields.values(), key=lambda f: f[3]):
        if ctype == "char":
            out[name] = values[k].split(b"\0", 1)[0]
            k += 1
        elif count:
            out[name] = values[k:k + count]
            k += count
        else:
            out[name] = values[k]
            k += 1
    return out


def ack_command(msgid, payload):
    """The command a COMMAND_ACK answers (None for any other message)."""
    if msgid != _MSG_COMMAND_ACK:
        return None
    p = bytes(payload[:2]).ljust(2, b"\0")
    return p[0] | p[1] << 8
