"""The saved corpus (tests/fuzz/corpus/<dialect>.txt): inputs that made the vehicle answer
something no earlier input had, kept in the tree and grown by every run of the
MicroPython engine (live.py).

One line an input: its bytes in hex, then the answers it was kept for (features). A
feature names what the vehicle sent back, reduced to what tells code paths apart and
bounded whatever the input: a COMMAND_ACK's command (one the vehicle has, or "other")
and result, a MISSION_ACK's type and plan type, a STATUSTEXT's severity, first and last
words, an FTP reply's opcodes and error, a contained fault's source and type, or just a
message id. The file's features are those found; an input is saved when its answers
hold a new one.
"""
import os
import re

from fuzz import wire

HERE = os.path.dirname(os.path.abspath(__file__))
DIR = os.path.join(HERE, "corpus")
MAX_LINE_BYTES = 1024  # an input longer than this is not saved whole: its first bytes are

_WORD = re.compile(r"^[A-Za-z_:]+$")
# Message ids whose answers say more than their id (fields by name, per dialect layouts).
_DETAIL = {
    "COMMAND_ACK": ("command", "result"),
    "MISSION_ACK": ("type", "mission_type"),
    "MISSION_COUNT": ("mission_type",),
    "MISSION_REQUEST": ("mission_type",),
    "MISSION_REQUEST_INT": ("mission_type",),
    "PARAM_VALUE": ("param_type",),
    "CHANGE_OPERATOR_CONTROL_ACK": ("control_request", "ack"),
}
_PLAN_TYPES = (0, 1, 2, 255)
_FTP_OPCODES = tuple(range(16)) + (128, 129)


def path(dialect):
    return os.path.join(DIR, dialect + ".txt")


def load(dialect):
    """-> ([input bytes], {feature})"""
    inputs, features = [], set()
    p = path(dialect)
    if not os.path.exists(p):
        return inputs, features
    with open(p) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            data, *found = line.split(" ")
            inputs.append(bytes.fromhex(data))
            features.update(found)
    return inputs, features


def save(dialect, data, features):
    """Append one input and the features it was kept for."""
    os.makedirs(DIR, exist_ok=True)
    with open(path(dialect), "a") as f:
        f.write("%s %s\n" % (bytes(data[:MAX_LINE_BYTES]).hex(), " ".join(sorted(features))))


class Features:
    """Names the features of a dialect's answers (commands: the vehicle's command ids)."""

    def __init__(self, table, commands):
        self.table = table
        self.commands = set(commands)
        self.names = {msgid: lay.name for msgid, lay in table.items()}

    def of(self, msgid, payload):
        name = self.names.get(msgid)
        if name is None:
            return "msg-%d" % msgid
        if name == "STATUSTEXT":
            f = wire.decode(self.table, msgid, payload)
            words = f["text"].decode(errors="replace").split() or ["-"]
            return "text-%d:%s:%s" % (f["severity"], _word(words[0]), _word(words[-1]) if len(words) > 1 else "")
        if name == "FILE_TRANSFER_PROTOCOL":
            p = bytes(payload[3:]).ljust(13, b"\0")  # the FTP header after network, system, component
            error = p[12] if p[3] == 129 else 0  # NAK: its first data byte
            return "ftp-%s-%s-%d" % (_known(p[3], _FTP_OPCODES), _known(p[5], _FTP_OPCODES), error)
        fields = _DETAIL.get(name)
        if not fields:
            return name
        f = wire.decode(self.table, msgid, payload)
        if "command" in f:
            f["command"] = _known(f["command"], self.commands)
        if "mission_type" in f:
            f["mission_type"] = _known(f["mission_type"], _PLAN_TYPES)
        return name + "".join("-%s" % f.get(k) for k in fields)


def _known(value, values):
    return value if value in values else "other"


def _word(w):
    return w if _WORD.match(w) else "#"


def fault(line):
    """The feature of a console fault line: its source and type, not its count."""
    return "fault:" + re.sub(r" \(\d+\)$", "", line).replace(" ", "_")


def mutate(rng, data, pool):
    data = bytearray(data)
    for _ in range(rng.randrange(1, 5)):
        what = rng.randrange(5)
        if what == 0 and data:
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        elif what == 1 and data:
            data[rng.randrange(len(data))] = rng.randrange(256)
        elif what == 2:
            k = rng.randrange(len(data) + 1)
            data[k:k] = rng.randbytes(rng.randrange(1, 8))
        elif what == 3 and len(data) > 2:
            k = rng.randrange(1, len(data))
            del data[k:k + rng.randrange(1, 8)]
        else:
            other = rng.choice(pool)
            k = rng.randrange(len(data) + 1)
            data[k:] = other[rng.randrange(len(other)):]
    return bytes(data[:4096])
