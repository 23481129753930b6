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
"""
import os

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
        if ls.by_id and set(ls.by_id) != seen:
            raise Broken("link %s: stream index %s, streams %s" % (ls.link.name, sorted(ls.by_id), sorted(seen)))
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
