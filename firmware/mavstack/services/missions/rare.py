"""The mission requests a ground station seldom sends: the seed's partial lists
(MISSION_REQUEST_PARTIAL_LIST, its items pushed at a share of the link, and
MISSION_WRITE_PARTIAL_LIST), MISSION_CLEAR_ALL, MISSION_SET_CURRENT, and an item that
comes outside an upload (the repeat of an upload's last item whose ACK was lost).
Loaded on the first of them (Missions._on_rare), or at start-up on a board that locks
its heap (HEAP_LOCK): until a ground station asks, a board short of RAM keeps this code
out of its heap. Once loaded, nothing here allocates. m is the missions service, t its
transfer (transfer.py). Reference: docs/services/missions.md.
"""
from ...compat import const, ticks_diff
from ...fields import i16, u16
from ...link import RANK_FILL
from .transfer import CHANGE, EVERY, IDLE, PUSH

_MSG_REQUEST_PARTIAL_LIST = const(37)
_MSG_WRITE_PARTIAL_LIST = const(38)
_MSG_SET_CURRENT = const(41)
_MSG_CLEAR_ALL = const(45)
_ACCEPTED = const(0)
_NO_SPACE = const(4)
_INVALID_SEQUENCE = const(13)
_TYPE_ALL = const(255)
_ITEM_FRAME_BYTES = const(50)  # a MAVLink 2 MISSION_ITEM_INT, for pacing pushed items
_PUSH_SHARE = const(2)  # pushed items use at most 1/2 of the link
# Credit for pushed items: elapsed ms * bytes/s must stay a small int. The credit is
# full (4 frames) well within a second on any link of 400 bytes/s or more, and at
# 1 MB/s four frames go out every millisecond, so neither cap is ever felt.
_PUSH_MAX_MS = const(1000)
_PUSH_MAX_RATE = const(0x100000)


def on(m, link, p):
    """A frame of one of these messages (or a stray MISSION_ITEM[_INT]) from link."""
    msgid = link.rx.msgid
    if msgid == _MSG_REQUEST_PARTIAL_LIST:
        _request_partial(m, link, p)
    elif msgid == _MSG_WRITE_PARTIAL_LIST:
        _write_partial(m, link, p)
    elif msgid == _MSG_CLEAR_ALL:
        _clear_all(m, link, p)
    elif msgid == _MSG_SET_CURRENT:
        _set_current(m, link, p)
    else:
        _stray(m, link, p)


def _write_partial(m, link, p):
    store = m.store_for(link, p)
    if store is None:
        return
    start = i16(p, 0)
    end = i16(p, 2)
    # The seed: a start beyond the current list is rejected (0 always starts a list).
    if start < 0 or end < start or (start > 0 and start >= store.count):
        m.reply(link, _INVALID_SEQUENCE, store.mission_type)
    elif end >= store.capacity:  # the plan would have end + 1 items
        m.reply(link, _NO_SPACE, store.mission_type)
    else:
        m.transfer.end = end
        _partial(m.transfer, link, store, start)


def _partial(t, link, store, start):
    """Upload items start .. t.end into the plan in force."""
    t.count = t.end + 1 if t.end >= store.count else store.count
    t.upload(link, store, start, store.count)


def _stray(m, link, p):
    # The ACK of a completed upload was lost: the ground station repeats the last item.
    rx = link.rx
    mt = p[37] if m.has_type else 0
    if (m.transfer.state == IDLE and u16(p, 28) == m.done_seq and link is m.done_link
            and rx.sysid << 16 | rx.compid << 8 | mt == m.done_key):
        m.reply(link, _ACCEPTED, mt)


def _request_partial(m, link, p):
    store = m.store_for(link, p)
    if store is None:
        return
    start = i16(p, 0)
    end = i16(p, 2)
    if end < 0 or end >= store.count:
        end = store.count - 1  # -1: to the end of the list
    if start < 0 or start > end:
        m.reply(link, _INVALID_SEQUENCE, store.mission_type)
        return
    m.transfer.start(link, PUSH, store)  # (no local for it: see docs/design.md, function frames)
    m.transfer.seq = start
    m.transfer.end = end
    m.transfer.credit = _ITEM_FRAME_BYTES
    push(m.transfer, m.transfer.sent)


def push(t, now):
    """The items of a partial list (transfer t) go out at a share of the link's capacity
    (tick), and only while the link's byte budget has room for them at RANK_FILL (after
    streams)."""
    link = t.link
    elapsed = ticks_diff(now, t.sent)
    if elapsed > 0:
        t.sent = now
        credit = t.credit + ((elapsed if elapsed < _PUSH_MAX_MS else _PUSH_MAX_MS)
                             * (link.bytes_per_s if link.bytes_per_s < _PUSH_MAX_RATE else _PUSH_MAX_RATE)
                             // (1000 * _PUSH_SHARE))
        t.credit = credit if credit < 4 * _ITEM_FRAME_BYTES else 4 * _ITEM_FRAME_BYTES
    while (t.credit >= _ITEM_FRAME_BYTES and t.seq <= t.end
           and link.can_send(_ITEM_FRAME_BYTES, RANK_FILL)):
        t.credit -= _ITEM_FRAME_BYTES
        t.progress = now
        t.send_item(link, t.store, t.seq, t.as_int)
        t.seq += 1
    if t.seq > t.end:
        t.state = IDLE


def _clear_all(m, link, p):
    if not m.ep.for_us(p[0], p[1]):
        return
    mt = m.admit(link, p[2] if m.has_type else 0, CHANGE | EVERY)
    if mt >= 0:
        m.reply(link, _clear_types(m, mt), mt)


def _clear_types(m, mt):
    result = _ACCEPTED
    for t in range(3):
        store = m.stores[t]
        if store is not None and (mt == _TYPE_ALL or mt == t):
            result = m.clear(store) or result  # the last failure is reported
    return result


def _set_current(m, link, p):
    if not m.ep.for_us(p[2], p[3]):
        return
    runner = m.runner
    if runner is not None and m.ep.allows(link) and runner.set_current(u16(p, 0)):
        return  # MISSION_CURRENT follows from the change
    m.ep.statustext(4, b"Mission: cannot set current item")  # MAV_SEVERITY_WARNING (bytes: no heap)
    m.send_current(link)
