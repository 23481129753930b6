"""The streams service: which message goes out on which link, how often.

Every link keeps, per message, the interval in force: the board's DEFAULT_STREAMS, or
what a ground station set with SET_MESSAGE_INTERVAL or the seed's REQUEST_DATA_STREAM
(by MAV_DATA_STREAM group, GROUPS below); GET_MESSAGE_INTERVAL is answered with the
interval achieved. Each tick the scheduler (scheduler.py) sends what is due within the
link's budget. The service also makes ep.telemetry, the slots the application writes
(telemetry.py). Reference: docs/services/streams.md.
"""
from struct import pack_into

from ...link import RANK_OTHER, RANK_AUTO
from ...compat import const, ticks_diff, ticks_add, to_grid
from ...fields import u16
from .scheduler import MAX_INTERVAL_US, LinkStreams, Stream, fit, measure, run
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
_MIN_INTERVAL_US = const(1000)  # one send per main-loop tick at most

# The seed's data stream groups, after ArduPilot's historical grouping: (MAV_DATA_STREAM,
# message ids), a message in one group; 0 (ALL) is every group.
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


def _find(streams, msgid):
    """The Stream of msgid in a link's list, None if it has none (requests only: a few
    dozen at most, and no dict to hold)."""
    for s in streams:
        if s.msgid == msgid:
            return s
    return None


class Streams:
    NAME = "streams"

    def __init__(self, defaults=()):
        self.defaults = defaults  # ((msgid, hz), ...)
        self.links = []
        self._rescale_at = 0

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
            fit(ls, self.ep.producers)

    def _stream(self, ls, msgid, create=True):
        s = _find(ls.streams, msgid)
        if s is None and create and self.ep.has(msgid):
            s = self._create(ls, msgid)
        return s

    def _create(self, ls, msgid):
        """A message streamed for the first time: a few objects -> its Stream, None if
        the heap is locked (or full): then it is not streamed. (Apart from _stream,
        which every request runs, to keep that one's frame small.)"""
        try:
            self._new_stream(ls, msgid)
        except MemoryError:  # (raised without allocating; the list did not take it)
            return None
        return _find(ls.streams, msgid)

    def _new_stream(self, ls, msgid):
        info = self.ep.dialect.CRC_LEN[msgid]
        ls.streams.append(Stream(msgid, self.ep.producers.get(msgid), (info >> 16) + 12))

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
            # On the grid of its interval from tick 0: streams whose intervals divide
            # each other fall due together and go in one tick (one wake of the loop).
            s.due = ticks_add(now, -now % (s.step_ms or 1))
            s.frac = 0

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
        if interval_us > MAX_INTERVAL_US:
            interval_us = MAX_INTERVAL_US
        s.requested_us = interval_us
        self._apply(ls, s, self.ep.now)
        fit(ls, self.ep.producers)
        self.ep.wake()  # the new deadline counts from the next pass
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

    # --- protocol handlers (small frames: links by index, payloads a field or two at a
    # time; see docs/design.md) ----------------------------------------------------------

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
        -> False if the group is unknown. The groups are walked in place, by index: a
        busy or hostile ground station may send this at any rate, and it must ask
        nothing of the heap (a locked board has none to give)."""
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

    # --- every tick ------------------------------------------------------------------

    def tick(self, now):
        if len(self.links) != len(self.ep.links):
            self._sync_links(now)
        if not -_RESCALE_MS <= ticks_diff(now, self._rescale_at) < 0:  # due, or the clock jumped
            self._rescale_at = ticks_add(now, to_grid(now, _RESCALE_MS))
            for ls in self.links:
                measure(ls, now)
                fit(ls, self.ep.producers)
        wait = ticks_diff(self._rescale_at, now)
        for ls in self.links:
            run(ls, now)
            if ls.wait < wait:
                wait = ls.wait
        return wait


def create(ep):
    return ep.add(Streams(getattr(getattr(ep, "board", None), "DEFAULT_STREAMS", ())))
