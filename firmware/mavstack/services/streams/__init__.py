"""Telemetry streams: which message goes out on which link, how often, within the
link's bandwidth.

Every link keeps, per message, the interval in force: the board's default
(board.DEFAULT_STREAMS, ((msgid, hz), ...), sent without being asked), or what a
ground station set with MAV_CMD_SET_MESSAGE_INTERVAL (511; -1 disables, 0 restores
the default; param7 response target 0 or 1: the requester's link, 2: every link),
or with the seed's REQUEST_DATA_STREAM (#66; req_message_rate in Hz, start_stop;
answered with DATA_STREAM #67). MAV_CMD_GET_MESSAGE_INTERVAL (510) is answered
with MESSAGE_INTERVAL (#244) carrying the interval actually achieved.
Messages come from endpoint.producers (telemetry slots, status, missions).

The seed's data stream groups, after ArduPilot's historical grouping (a message
belongs to one group; ALL (0) sets every group):

    1  RAW_SENSORS      RAW_IMU, SCALED_IMU, RAW_PRESSURE, SCALED_PRESSURE, HIGHRES_IMU
    2  EXTENDED_STATUS  SYS_STATUS, GPS_RAW_INT, GPS_STATUS, MISSION_CURRENT,
                        NAV_CONTROLLER_OUTPUT, EXTENDED_SYS_STATE
    3  RC_CHANNELS      RC_CHANNELS_RAW, RC_CHANNELS, SERVO_OUTPUT_RAW
    4  RAW_CONTROLLER   RC_CHANNELS_SCALED
    6  POSITION         GLOBAL_POSITION_INT, LOCAL_POSITION_NED
    10 EXTRA1           ATTITUDE, ATTITUDE_QUATERNION
    11 EXTRA2           VFR_HUD
    12 EXTRA3           SYSTEM_TIME, BATTERY_STATUS, OPTICAL_FLOW

Scheduling: each stream has a deadline in ticks_ms; after a send the deadline
moves on by the interval (kept in microseconds, remainder carried), not from
"now", so the long-run rate is exact. A stream that fell behind catches up by one
message on the next tick; one that fell a whole interval behind (a stall) lets the
missed ones go instead of bursting. New streams start at staggered phases.

Bandwidth: each link has a byte budget (link.py) that every send pays from.
Streams go at RANK_BULK: after HEARTBEAT and the answers to ground stations,
ahead of parameter lists and floods. A due stream goes when the link can pay
for it at that rank (link.can_send) and otherwise stays due for a later tick,
so the loop never waits. Once a second the streams are fitted to what the
answers left (bytes sent outside the scheduler, less lists and floods, which
yield to streams anyway): when requests exceed it, every interval is stretched
by the same factor (each message keeps the same share of what it asked for),
and that achieved interval is what MESSAGE_INTERVAL reports.
"""
from struct import pack_into

from ...link import TX_WRAP, RANK_BULK, RANK_OTHER, RANK_AUTO
from ...compat import const, ticks_diff, ticks_add
from ...fields import u16
from .telemetry import Telemetry

AFTER = ("inputs", "seed_telemetry")  # their slots stream by default
USES = ("commands", "status")  # the command being answered; the battery for SYS_STATUS

_MSG_REQUEST_DATA_STREAM = const(66)
_MSG_DATA_STREAM = const(67)
_MSG_MESSAGE_INTERVAL = const(244)
_CMD_GET_MESSAGE_INTERVAL = const(510)
_CMD_SET_MESSAGE_INTERVAL = const(511)
_CMD_REQUEST_MESSAGE = const(512)
_ACCEPTED = const(0)
_DENIED = const(2)

_RESCALE_MS = const(1000)  # how often streams are fitted to the measured budget
_MARGIN_DIV = const(20)  # keep 1/20 of the budget for priority bursts
_FLOOR_DIV = const(10)  # streams keep at least 1/10 of the budget in the fit
_DEMAND_MAX = const(0x20000)  # B/s: demand << 12 stays below 2^30 (_stretch)
_RATIO_MAX = const(0x40000)  # 64x in 1/4096: (interval & 4095) * ratio stays below 2^30
_MIN_INTERVAL_US = const(1000)  # one send per main-loop tick at most
_MAX_INTERVAL_US = const(1000000000)  # below 2^30; also the most a fit stretches to
_PHASE_STEP_MS = const(37)

# (MAV_DATA_STREAM, message ids); see the table above.
GROUPS = (
    (1, (27, 26, 28, 29, 105)),
    (2, (1, 24, 25, 42, 62, 245)),
    (3, (35, 65, 36)),
    (4, (34,)),
    (6, (33, 32)),
    (10, (30, 31)),
    (11, (74,)),
    (12, (2, 147, 100)),
)


def group(stream_id):
    """Message ids of a MAV_DATA_STREAM (0: all of them), or None if unknown."""
    if stream_id == 0:
        ids = []
        for g in GROUPS:
            ids.extend(g[1])
        return ids
    for g in GROUPS:
        if g[0] == stream_id:
            return g[1]
    return None


class Stream:
    """One message on one link."""

    def __init__(self, msgid, send, cost):
        self.msgid = msgid
        self.send = send  # producer: send(link) -> bool
        self.cost = cost  # bytes on the wire per frame (last measured)
        self.default_us = 0  # board default interval, 0: none
        self.requested_us = 0  # 0: default, -1: disabled, > 0: set by a ground station
        self.interval_us = 0  # in force (requested or default), 0: off
        self.achieved_us = 0  # after fitting to the budget
        self.step_ms = 0
        self.due = 0
        self.frac = 0  # microseconds carried between deadlines
        self.live = True  # the producer had something to send last time
        self.sent = 0


def _stretch(interval_us, demand, avail):
    """interval_us * demand / avail, rounded up, with no int of 2^30 or more on the way
    (a heap object on a 32-bit board): the ratio as a fraction of 4096 (demand is below
    _DEMAND_MAX), the product in two parts, and _MAX_INTERVAL_US at most."""
    r = ((demand << 12) + avail - 1) // avail
    if r > _RATIO_MAX:  # over 64 times the budget: whole multiples are fine enough
        q = (demand + avail - 1) // avail
        return _MAX_INTERVAL_US if interval_us > _MAX_INTERVAL_US // q else interval_us * q
    hi = (interval_us >> 12) * r
    if hi >= _MAX_INTERVAL_US:
        return _MAX_INTERVAL_US
    return hi + (((interval_us & 4095) * r + 4095) >> 12)


class LinkStreams:
    """The streams of one link and what its answers took of its budget."""

    def __init__(self, link, now):
        self.link = link
        self.streams = []
        self.by_id = {}
        self.now = now  # this tick's
        self.start = 0  # first stream looked at next tick (rotates, for fairness)
        self.win_start = now  # window over which priority traffic is measured
        self.win_tx = link.tx_bytes
        self.win_low = link.tx_low
        self.win_stream = 0
        self.priority_bps = 0


class Streams:
    NAME = "streams"

    def __init__(self, defaults=()):
        self.defaults = defaults  # ((msgid, hz), ...)
        self.links = []
        self._phase = 0
        self._rescale_at = 0
        self._guard = _MemoryGuard()

    def attach(self, ep):
        self.ep = ep
        tm = getattr(ep, "telemetry", None)
        if tm is None:
            tm = ep.telemetry = Telemetry(ep)
        self.telemetry = tm
        self._rescale_at = ep.now
        ep.on(_MSG_REQUEST_DATA_STREAM, self._on_request_data_stream)
        ep.commands[_CMD_SET_MESSAGE_INTERVAL] = self._on_set_interval
        if ep.has(_MSG_MESSAGE_INTERVAL):
            self._interval_fmt = ep.fmt(_MSG_MESSAGE_INTERVAL)
            ep.commands[_CMD_GET_MESSAGE_INTERVAL] = self._on_get_interval
            ep.producers[_MSG_MESSAGE_INTERVAL] = self.send_message_interval
        self._sync_links(ep.now)

    # --- configuration (ground-station paced; may allocate) -----------------------

    def _sync_links(self, now):
        for link in self.ep.links[len(self.links):]:
            ls = LinkStreams(link, now)
            self.links.append(ls)
            for msgid, hz in self.defaults:
                s = self._stream(ls, msgid)
                if s is not None:
                    s.default_us = int(1000000 / hz) if hz > 0 else 0
                    self._apply(ls, s, now)
            self._fit(ls)

    def _stream(self, ls, msgid, create=True):
        s = ls.by_id.get(msgid)
        if s is None and create and self.ep.has(msgid):
            s = self._create(ls, msgid)
        return s

    def _create(self, ls, msgid):
        """A message streamed for the first time: a few objects -> its Stream, None if
        the heap is locked (or full): then it is not streamed. (Apart from _stream,
        which every request runs: the with block's words would put its frame state on
        the heap.)"""
        with self._guard:
            self._new_stream(ls, msgid)
        if self._guard.failed:
            if ls.by_id.get(msgid) is not None and len(ls.streams) != len(ls.by_id):
                del ls.by_id[msgid]  # (the list could not take it)
            return None
        return ls.by_id.get(msgid)

    def _new_stream(self, ls, msgid):
        info = self.ep.dialect.CRC_LEN[msgid]
        s = Stream(msgid, self.ep.producers.get(msgid), (info >> 16) + 12)
        ls.by_id[msgid] = s
        ls.streams.append(s)

    def _apply(self, ls, s, now):
        want = s.requested_us if s.requested_us else s.default_us
        if want < 0:
            want = 0
        elif 0 < want < _MIN_INTERVAL_US:
            want = _MIN_INTERVAL_US
        if want == s.interval_us:
            return
        s.interval_us = want
        s.achieved_us = want
        s.step_ms = want // 1000
        if want:
            # Staggered start so that streams set together do not fall due together.
            s.due = ticks_add(now, self._phase % (s.step_ms + 1))
            s.frac = 0
            self._phase += _PHASE_STEP_MS

    def set_interval(self, link, msgid, interval_us):
        """Interval for msgid on a link: > 0 us, 0 the board default, -1 off.
        Returns False if the endpoint cannot produce that message."""
        ls = self._links_state(link)
        if msgid not in self.ep.producers or msgid == _MSG_MESSAGE_INTERVAL or interval_us < -1:
            return False
        s = self._stream(ls, msgid)
        if s is None:
            return False
        if s.send is None:
            s.send = self.ep.producers[msgid]
        if interval_us > _MAX_INTERVAL_US:
            interval_us = _MAX_INTERVAL_US
        s.requested_us = interval_us
        self._apply(ls, s, self.ep.now)
        self._fit(ls)
        return True

    def set_rate(self, link, msgid, hz):
        """set_interval in Hz (0 switches the message off)."""
        return self.set_interval(link, msgid, int(1000000 / hz) if hz > 0 else -1)

    def interval(self, link, msgid):
        """As MESSAGE_INTERVAL reports it: the achieved interval in us, -1 when the
        message is not streamed, 0 when the endpoint cannot produce it."""
        if msgid not in self.ep.producers:
            return 0
        s = self._stream(self._links_state(link), msgid, False)
        if s is None or s.interval_us <= 0:
            return -1
        return s.achieved_us

    def _links_state(self, link):
        if link.index >= len(self.links):
            self._sync_links(self.ep.now)
        return self.links[link.index]

    # --- protocol handlers -----------------------------------------------------------

    # The handlers keep their frames within the ~11 words MicroPython holds off the heap
    # too (links by index, payloads a field or two at a time).
    def _on_set_interval(self, cmd):
        if cmd.int(7) == 2:
            ok = True
            i = 0
            while i < len(self.ep.links):
                ok = self.set_interval(self.ep.links[i], cmd.int(1), cmd.int(2)) and ok
                i += 1
        else:
            ok = self.set_interval(cmd.link, cmd.int(1), cmd.int(2))
        return _ACCEPTED if ok else _DENIED

    def _on_get_interval(self, cmd):
        cmd.reply = _MSG_MESSAGE_INTERVAL  # sent right after the ACK
        return _ACCEPTED

    def send_message_interval(self, link):
        """Producer of MESSAGE_INTERVAL, in answer to GET_MESSAGE_INTERVAL (param1: the
        message) or REQUEST_MESSAGE 244 (param2: the message)."""
        msgid = self._asked()
        if msgid is None:
            return False
        interval = self.interval(link, msgid)
        off = link.begin()
        pack_into("<i", link.txbuf, off, interval)  # MESSAGE_INTERVAL: interval_us, message_id
        pack_into("<H", link.txbuf, off + 4, msgid & 0xFFFF)
        return link.send(_MSG_MESSAGE_INTERVAL)

    def _asked(self):
        """The message id the command being answered asks about, or None."""
        commands = self.ep.services.get("commands")
        if commands is None:
            return None
        cmd = commands.cmd
        if cmd.command == _CMD_GET_MESSAGE_INTERVAL:
            return cmd.int(1)
        if cmd.command == _CMD_REQUEST_MESSAGE and cmd.int(1) == _MSG_MESSAGE_INTERVAL:
            return cmd.int(2)
        return None

    def _on_request_data_stream(self, link, p):
        # REQUEST_DATA_STREAM: req_message_rate, target_system, target_component, req_stream_id, start_stop
        if not self.ep.for_us(p[2], p[3]):
            return
        rate = u16(p, 0) if p[5] else 0  # 0: stop
        if not self._set_group(link, p[4], rate):
            rate = 0
        # DATA_STREAM: message_rate, stream_id, on_off
        off = link.begin()
        pack_into("<H", link.txbuf, off, rate)
        link.txbuf[off + 2] = p[4]
        link.txbuf[off + 3] = 1 if rate else 0
        link.rank = RANK_OTHER  # a cheap one-off: dropped when only floods' share is left
        link.send(_MSG_DATA_STREAM)
        link.rank = RANK_AUTO

    def _set_group(self, link, stream_id, rate):
        """The messages of a group (0: all) this endpoint produces at rate Hz (0: off)
        -> False if the group is unknown. The groups are walked in place, in functions
        of few locals: a busy or hostile ground station may send this at any rate, and
        it must ask nothing of the heap (a locked board has none to give)."""
        if stream_id != 0 and group(stream_id) is None:
            return False
        self._set_groups(link, stream_id, 1000000 // rate if rate else -1)
        return True

    def _set_groups(self, link, stream_id, interval):
        g = 0
        while g < len(GROUPS):
            if stream_id == 0 or GROUPS[g][0] == stream_id:
                self._set_ids(link, GROUPS[g][1], interval)
            g += 1

    def _set_ids(self, link, ids, interval):
        i = 0
        while i < len(ids):
            if ids[i] in self.ep.producers:
                self.set_interval(link, ids[i], interval)
            i += 1

    # --- the scheduler (every tick; allocation-free) -------------------------------
    # In small functions with few locals: MicroPython takes a frame state of more than
    # about 11 words (locals plus value stack; a for loop's iterator is four) from the
    # heap on every call.

    def tick(self, now):
        if len(self.links) != len(self.ep.links):
            self._sync_links(now)
        if not -_RESCALE_MS <= ticks_diff(now, self._rescale_at) < 0:  # due, or the clock jumped
            self._rescale_at = ticks_add(now, _RESCALE_MS)
            for ls in self.links:
                self._measure(ls, now)
                self._fit(ls)
        for ls in self.links:
            _run(ls, now)

    def _measure(self, ls, now):
        """Bytes per second the link sent outside the scheduler since the last look."""
        span = ticks_diff(now, ls.win_start)
        tx = ls.link.tx_bytes
        low = ls.link.tx_low  # lists and floods: they yield to streams, so they do not count
        if span > 0:
            other = ((tx - ls.win_tx) & TX_WRAP) - ((low - ls.win_low) & TX_WRAP) - ls.win_stream
            ls.priority_bps = (other if other > 0 else 0) * 1000 // span
        ls.win_start = now
        ls.win_tx = tx
        ls.win_low = low
        ls.win_stream = 0

    def _fit(self, ls):
        """Stretch every interval by the same factor when requests exceed the budget."""
        bps = ls.link.bytes_per_s
        avail = bps - ls.priority_bps - bps // _MARGIN_DIV
        if avail < bps // _FLOOR_DIV:
            avail = bps // _FLOOR_DIV
        demand = self._demand(ls)
        while demand >= _DEMAND_MAX:  # keep the ratio's numerator below 2^30 (see _stretch)
            demand >>= 1
            avail = (avail >> 1) or 1
        i = 0
        while i < len(ls.streams):
            s = ls.streams[i]
            if s.interval_us > 0 and demand > avail:
                s.achieved_us = _stretch(s.interval_us, demand, avail)
            else:
                s.achieved_us = s.interval_us
            s.step_ms = s.achieved_us // 1000
            i += 1

    def _demand(self, ls):
        """Bytes per second the link's streams ask for (those with something to send)."""
        demand = 0
        for s in ls.streams:
            if s.send is None:
                s.send = self.ep.producers.get(s.msgid)
            if s.interval_us > 0 and s.live and s.send is not None:
                demand += s.cost * 1000000 // s.interval_us
        return demand


class _MemoryGuard:
    """`with guard:` a MemoryError in the block ends there (guard.failed says so): a
    request that would need a new object on a board whose heap is locked is refused,
    not fatal. (MicroPython raises MemoryError without allocating.)"""

    def __init__(self):
        self.failed = False

    def __enter__(self):
        self.failed = False

    def __exit__(self, kind, e, tb):
        self.failed = kind is MemoryError
        return self.failed


# The per-tick path as plain functions (no self: one local fewer, so the loop keeps its
# streams and their count in locals and still fits).
def _run(ls, now):
    """Send what is due on one link, from ls.start on, while its budget lasts."""
    streams = ls.streams
    n = len(streams)
    if n == 0:
        return
    ls.now = now
    i = ls.start
    ls.start = i + 1 if i + 1 < n else 0
    k = n
    while k:
        k -= 1
        s = streams[i]
        i = i + 1 if i + 1 < n else 0
        if s.achieved_us <= 0 or s.send is None:
            continue
        late = ticks_diff(now, s.due)
        if late < 0:
            if late < -2 * s.step_ms - 2:  # the clock jumped back: start again
                s.due = now
            continue
        if not _send(ls, s):
            return


def _send(ls, s):
    """Send a due stream -> False when the link cannot pay for more now (it stays due)."""
    link = ls.link
    if not link.can_send(s.cost, RANK_BULK):
        return False
    before = link.tx_bytes
    held = link.tx_held + link.tx_dropped
    link.rank = RANK_BULK
    ok = s.send(link)
    link.rank = RANK_AUTO
    if ok:
        _sent(ls, s, before)
    elif link.tx_held + link.tx_dropped != held:
        return False
    else:
        s.live = False  # nothing written yet (or not sendable on this link)
    _next_due(s, ls.now)
    return True


def _sent(ls, s, before):
    sent = (ls.link.tx_bytes - before) & TX_WRAP
    s.cost = sent
    s.sent += 1
    s.live = True
    ls.win_stream += sent


def _next_due(s, now):
    # The deadline moves on by the interval (remainder carried), not from now.
    f = s.frac + s.achieved_us
    step = f // 1000
    s.frac = f - step * 1000
    s.due = ticks_add(s.due, step)
    if ticks_diff(now, s.due) >= step:
        s.due = now  # a whole interval behind: let the missed ones go


def create(ep):
    return ep.add(Streams(getattr(getattr(ep, "board", None), "DEFAULT_STREAMS", ())))
