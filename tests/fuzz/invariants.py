"""What must hold after every fuzzed batch, whatever the frames were.

- parameter table: every value one its parameter may take; the stored file decodes,
  and holds the values in force unless a change is waiting for its save;
- mission store: each plan within its capacity and readable, the plan in storage (as a
  fresh store loads it) the plan in force, the transfer state coherent;
- scheduler: every stream's interval, due time and the link's credit sane;
- signing: on exactly when the key is not zero; the stored key the key in force.

`Snapshot` is the storage directory's bytes; `unchanged(before, after)` names the files
that differ. A batch that holds no legitimate write (every frame aimed at another
vehicle) must leave storage byte for byte as it was, and the values in force too.

`stored(...)` and `in_force(...)` hold the same for a vehicle in another process (the
MicroPython engine): its storage read here, what is in force asked over MAVLink.
"""
import os
import struct

from mavstack.services.params import table as param_table
from mavstack.services.missions.store import MissionStore, RECORD_SIZE
from mavstack.storage import Storage, checksum


class Broken(AssertionError):
    """An invariant does not hold."""


def snapshot(root):
    out = {}
    for name in sorted(os.listdir(root)):
        with open(os.path.join(root, name), "rb") as f:
            out[name] = f.read()
    return out


def changed(before, after):
    names = set(before) | set(after)
    return sorted(n for n in names if before.get(n) != after.get(n))


def state(v):
    """What a legitimate write may change: parameter values, plans, the signing key."""
    p = v.params
    plans = tuple((s.count, s.gen, s.crc) if s is not None else None for s in v.missions.stores)
    return bytes(p._values), plans, bytes(v.signing.key)


def check(v, stored):
    """All invariants of FuzzVehicle v, given a snapshot of its storage just taken."""
    _params(v, stored)
    _missions(v)
    _streams(v)
    _signing(v, stored)


def _params(v, stored):
    p = v.params
    for i in range(p.count):
        if not p.valid(i, p._values, 4 * i):
            raise Broken("parameter %s holds %r, outside its type or range" % (p.name(i), p.value(i)))
    data = stored.get("params")
    if data is None:
        return
    fresh = _decoder(v)
    bad = fresh.unpack(data, len(data))
    if bad != 0:
        raise Broken("stored parameters do not decode (%d)" % bad)
    if not p.dirty:
        for i in range(p.count):
            name = p.name(i)
            if name == getattr(v.ep.board, "PARAM_SYSID", None):
                continue  # set from --sysid at start, not stored
            if bytes(fresh._loaded[4 * i:4 * i + 4]) != bytes(p._values[4 * i:4 * i + 4]):
                raise Broken("parameter %s: stored %r, in force %r, no save pending"
                             % (name, fresh._loaded[4 * i:4 * i + 4], p.value(i)))


_DECODERS = {}


def _decoder(v):
    """A table of the board's parameters to decode stored files with (made once)."""
    table = v.ep.board.PARAMS
    if id(table) not in _DECODERS:
        _DECODERS[id(table)] = param_table.ParamTable(table)
    return _DECODERS[id(table)]


def _missions(v):
    m = v.missions
    rec = bytearray(RECORD_SIZE)
    storage = Storage(v.storage)
    for s in m.stores:
        if s is None:
            continue
        if not 0 <= s.count <= s.capacity:
            raise Broken("%d plan: %d items, capacity %d" % (s.mission_type, s.count, s.capacity))
        if s.corrupt:
            raise Broken("%d plan found corrupt" % s.mission_type)
        for seq in range(s.count):
            if not s.read(seq, rec):
                raise Broken("%d plan: item %d unreadable" % (s.mission_type, seq))
        name = ("mission", "fence", "rally")[s.mission_type]
        fresh = MissionStore(storage, name, s.mission_type, s.capacity)
        try:
            if fresh.corrupt or (fresh.count, fresh.gen, fresh.crc) != (s.count, s.gen, s.crc):
                raise Broken("%s plan stored (count %d gen %d crc %04x corrupt %s) is not the plan in "
                             "force (count %d gen %d crc %04x)" % (name, fresh.count, fresh.gen, fresh.crc,
                                                                   fresh.corrupt, s.count, s.gen, s.crc))
        finally:
            fresh.close()
    t = m.transfer
    if t.state != 0:
        if t.store is None or t.link is None:
            raise Broken("a transfer under way without its store or link")
        if not 0 <= t.seq <= t.store.capacity + 1 or t.count > t.store.capacity:
            raise Broken("transfer at %d of %d (capacity %d)" % (t.seq, t.count, t.store.capacity))


def _streams(v):
    for ls in v.streams.links:
        seen = set()
        for s in ls.streams:
            if s.msgid in seen:
                raise Broken("stream %d twice on link %s" % (s.msgid, ls.link.name))
            seen.add(s.msgid)
            if s.interval_us < 0 or s.achieved_us < 0 or s.cost < 0:
                raise Broken("stream %d: interval %d achieved %d cost %d" % (s.msgid, s.interval_us,
                                                                          s.achieved_us, s.cost))
            if s.interval_us and s.achieved_us < s.interval_us:
                raise Broken("stream %d runs faster (%d us) than asked (%d us)" % (s.msgid, s.achieved_us,
                                                                                 s.interval_us))
        if getattr(ls, "priority_bps", 0) < 0:
            raise Broken("link %s: priority traffic %d B/s" % (ls.link.name, ls.priority_bps))


def _signing(v, stored):
    sg = v.signing
    if sg.enabled != any(sg.key):
        raise Broken("signing enabled=%s with key %s" % (sg.enabled, bytes(sg.key).hex()))
    data = stored.get("signing_key")
    if data is None:
        if sg.enabled:
            raise Broken("signing on, no key stored")
        return
    if len(data) != 42 or checksum(data[:40]) != data[40] | data[41] << 8:
        raise Broken("stored signing key corrupt")
    if data[:32] != bytes(sg.key):
        raise Broken("stored signing key %s, in force %s" % (data[:32].hex(), bytes(sg.key).hex()))


# --- a vehicle in another process: its storage read here ---------------------------------
PLANS = (("mission", "MISSION_CAPACITY"), ("fence", "FENCE_CAPACITY"), ("rally", "RALLY_CAPACITY"))


def stored(root, board, plan_types=3):
    """What the vehicle's storage holds, checked for sanity -> {"params": the values (4
    bytes each, by index) or None, "plans": [(count, opaque_id)], "key": the signing key
    or None}."""
    out = {"params": None, "plans": [], "key": None}
    table = _table(board)
    data = read_file(os.path.join(root, "params"))
    if data is not None:
        bad = table.unpack(data, len(data))
        if bad != 0:
            raise Broken("stored parameters do not decode (%d)" % bad)
        for i in range(table.count):
            if not table.valid(i, table._loaded, 4 * i):
                raise Broken("stored parameter %s is outside its type or range" % table.name(i))
        out["params"] = bytes(table._loaded)
    storage = Storage(root)
    rec = bytearray(RECORD_SIZE)
    for mission_type in range(plan_types):
        name, capacity = PLANS[mission_type]
        s = MissionStore(storage, name, mission_type, getattr(board, capacity))
        try:
            if s.corrupt or not 0 <= s.count <= s.capacity:
                raise Broken("stored %s plan: corrupt %s, %d items" % (name, s.corrupt, s.count))
            for seq in range(s.count):
                if not s.read(seq, rec):
                    raise Broken("stored %s plan: item %d unreadable" % (name, seq))
            out["plans"].append((s.count, s.plan_id))
        finally:
            s.close()
    data = read_file(os.path.join(root, "signing_key"))
    if data is not None:
        if len(data) != 42 or checksum(data[:40]) != data[40] | data[41] << 8:
            raise Broken("stored signing key corrupt")
        out["key"] = data[:32]
    return out


def read_file(path):
    """A file's bytes, None when there is none."""
    try:
        with open(path, "rb") as f:
            return f.read()
    except FileNotFoundError:
        return None


def in_force(board, held, params, plans):
    """What the vehicle says is in force (params: {index: (name, value bytes, type)} from
    PARAM_VALUEs; plans: [(count, opaque_id or None)] from MISSION_COUNTs) against
    `held`, what stored() read after the vehicle saved."""
    table = _table(board)
    values = held["params"]
    for i in range(table.count):
        name = table.name(i)
        got = params.get(i)
        if got is None or got[0].decode(errors="replace") != name:
            raise Broken("parameter %d: in force %r, the table says %s" % (i, got, name))
        if name == getattr(board, "PARAM_SYSID", None) or values is None:
            continue
        want = values[4 * i:4 * i + 4]
        if got[1] != want and got[1] != _c_cast(table, i, want):
            raise Broken("parameter %s: in force %s, stored %s" % (name, got[1].hex(), want.hex()))
    for mission_type, (have, want) in enumerate(zip(plans, held["plans"])):
        if have is None or have[0] != want[0] or (have[1] is not None and have[1] != want[1]):
            raise Broken("%s plan in force (count, id) %s, stored %s" % (PLANS[mission_type][0], have, want))


def _c_cast(table, i, raw):
    """An integer parameter's value as a float's bits (the C-cast encoding)."""
    if table.type(i) == 9:  # MAV_PARAM_TYPE_REAL32: no other encoding
        return raw
    code = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i"}[table.type(i)]
    return struct.pack("<f", struct.unpack(code, raw[:struct.calcsize(code)])[0])


_TABLES = {}


def _table(board):
    if id(board.PARAMS) not in _TABLES:
        _TABLES[id(board.PARAMS)] = param_table.ParamTable(board.PARAMS)
    return _TABLES[id(board.PARAMS)]
