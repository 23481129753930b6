"""The mission requests a ground station seldom sends, for missions.py: the seed's partial
lists (MISSION_REQUEST_PARTIAL_LIST, its items pushed at a share of the link, and
MISSION_WRITE_PARTIAL_LIST), MISSION_CLEAR_ALL, MISSION_SET_CURRENT, and an item that
comes outside an upload (the repeat of an upload's last item whose ACK was lost).

Loaded on the first of them (Missions._on_rare), or at start-up on a board that locks
its heap (HEAP_LOCK): until a ground station asks, a board short of RAM keeps this code
out of its heap. Once loaded, nothing here allocates (on a 32-bit board too), and each
function keeps within 11 words of locals and stack, as in missions.py. m is the
missions.Missions service; its state and helpers are used as its own methods use them.
"""
from ...compat import const, ticks_diff
from ...fields import i16, u16
from ...link import RANK_FILL

# As in missions.py.
_MSG_REQUEST_PARTIAL_LIST = const(37)
_MSG_WRITE_PARTIAL_LIST = const(38)
_MSG_SET_CURRENT = const(41)
_MSG_CLEAR_ALL = const(45)
_ACCEPTED = const(0)
_NO_SPACE = const(4)
_INVALID_SEQUENCE = const(13)
_TYPE_ALL = const(255)
_IDLE = const(0)
_PUSH = const(3)
_CHANGE = const(8)
_EVERY = const(16)
_ITEM_FRAME_BYTES = const(50)  # a MAVLink 2 MISSION_ITEM_INT, for pacing pushed items
_PUSH_SHARE = const(2)  # pushed items use at most 1/2 of the link
# Credit for pushed items: elapsed ms * bytes/s must stay a small int (< 2^30). The
# credit is full (4 frames) well within a second on any link of 400 bytes/s or more,
# and at 1 MB/s four frames go out every millisecond, so neither cap is ever felt.
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
    store = m._store(link, p)
    if store is None:
        return
    start = i16(p, 0)
    end = i16(p, 2)
    # The seed: a start beyond the current list is rejected (0 always starts a list).
    if start < 0 or end < start or (start > 0 and start >= store.count):
        m._reply(link, _INVALID_SEQUENCE, store.mission_type)
    elif end >= store.capacity:  # the plan would have end + 1 items
        m._reply(link, _NO_SPACE, store.mission_type)
    else:
        m.t_end = end
        _partial(m, link, store, start)


def _partial(m, link, store, start):
    """Upload items start .. m.t_end into the plan in force."""
    m.t_count = m.t_end + 1 if m.t_end >= store.count else store.count
    m.upload.start(link, store, start, store.count)


def _stray(m, link, p):
    # The ACK of a completed upload was lost: the ground station repeats the last item.
    rx = link.rx
    mt = p[37] if m.has_type else 0
    if (m.state == _IDLE and u16(p, 28) == m.done_seq and link is m.done_link
            and rx.sysid << 16 | rx.compid << 8 | mt == m.done_key):
        m._reply(link, _ACCEPTED, mt)


def _request_partial(m, link, p):
    store = m._store(link, p)
    if store is None:
        return
    start = i16(p, 0)
    end = i16(p, 2)
    if end < 0 or end >= store.count:
        end = store.count - 1  # -1: to the end of the list
    if start < 0 or start > end:
        m._reply(link, _INVALID_SEQUENCE, store.mission_type)
        return
    m._start(link, _PUSH, store)
    m.t_seq = start
    m.t_end = end
    m.t_credit = _ITEM_FRAME_BYTES
    push(m, m.t_sent)


def push(m, now):
    """The items of a partial list go out at a share of the link's capacity (tick), and
    only while the link's byte budget has room for them at RANK_FILL (after streams)."""
    link = m.t_link
    elapsed = ticks_diff(now, m.t_sent)
    if elapsed > 0:
        m.t_sent = now
        credit = m.t_credit + ((elapsed if elapsed < _PUSH_MAX_MS else _PUSH_MAX_MS)
                               * (link.bytes_per_s if link.bytes_per_s < _PUSH_MAX_RATE else _PUSH_MAX_RATE)
                               // (1000 * _PUSH_SHARE))
        m.t_credit = credit if credit < 4 * _ITEM_FRAME_BYTES else 4 * _ITEM_FRAME_BYTES
    while (m.t_credit >= _ITEM_FRAME_BYTES and m.t_seq <= m.t_end
           and link.can_send(_ITEM_FRAME_BYTES, RANK_FILL)):
        m.t_credit -= _ITEM_FRAME_BYTES
        m.t_progress = now
        m._send_item(link, m.t_store, m.t_seq, m.t_int)
        m.t_seq += 1
    if m.t_seq > m.t_end:
        m.state = _IDLE


def _clear_all(m, link, p):
    if not m.ep.for_us(p[0], p[1]):
        return
    mt = m._admit(link, p[2] if m.has_type else 0, _CHANGE | _EVERY)
    if mt >= 0:
        m._reply(link, _clear_types(m, mt), mt)


def _clear_types(m, mt):
    result = _ACCEPTED
    for t in range(3):
        store = m.stores[t]
        if store is not None and (mt == _TYPE_ALL or mt == t):
            result = m._clear(store) or result  # the last failure is reported
    return result


def _set_current(m, link, p):
    if not m.ep.for_us(p[2], p[3]):
        return
    runner = m.runner
    if runner is not None and m.ep.allows(link) and runner.set_current(u16(p, 0)):
        return  # MISSION_CURRENT follows from the change
    m.ep.statustext(4, "Mission: cannot set current item")  # MAV_SEVERITY_WARNING
    m.send_current(link)
