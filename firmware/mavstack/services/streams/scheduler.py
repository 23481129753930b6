"""The stream scheduler: each tick, send what is due on each link while its budget lasts,
and once a second fit every link's streams to what its answers left of the budget.

Stream (one message on one link) and LinkStreams (a link's streams) are the state; the
streams service configures them and calls measure(), fit() and run().
Reference: docs/services/streams.md.
"""
from ...link import TX_WRAP, RANK_BULK, RANK_AUTO
from ...compat import const, ticks_diff, ticks_add
from ...faults import PRODUCER

MAX_INTERVAL_US = const(1000000000)  # below 2^30; also the most a fit stretches to

_SLACK_MS = const(10)  # a stream may go this early, with others (endpoint.py's slack)
_WAIT_MAX_MS = const(1000)  # the most run() lets a link's streams wait (ls.wait)
_MARGIN_DIV = const(20)  # keep 1/20 of the budget for priority bursts
_FLOOR_DIV = const(10)  # streams keep at least 1/10 of the budget in the fit
_DEMAND_MAX = const(0x20000)  # B/s: demand << 12 stays below 2^30 (_stretch)
_RATIO_MAX = const(0x40000)  # 64x in 1/4096: (interval & 4095) * ratio stays below 2^30


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


class LinkStreams:
    """The streams of one link and what its answers took of its budget."""

    def __init__(self, link, now):
        self.link = link
        self.streams = []
        self.now = now  # this tick's
        self.start = 0  # first stream looked at next tick (rotates, for fairness)
        self.win_start = now  # window over which priority traffic is measured
        self.win_tx = link.tx_bytes
        self.win_low = link.tx_low
        self.win_stream = 0
        self.priority_bps = 0
        self.wait = 0  # ms from run()'s now to the first stream due (run sets it)


# --- the fit (once a second, and when a request changes an interval) -------------------

def measure(ls, now):
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


def fit(ls, producers):
    """Stretch every interval by the same factor when requests exceed the budget."""
    bps = ls.link.bytes_per_s
    avail = bps - ls.priority_bps - bps // _MARGIN_DIV
    if avail < bps // _FLOOR_DIV:
        avail = bps // _FLOOR_DIV
    demand = _demand(ls, producers)
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


def _demand(ls, producers):
    """Bytes per second the link's streams ask for (those with something to send)."""
    demand = 0
    for s in ls.streams:
        if s.send is None:
            s.send = producers.get(s.msgid)
        if s.interval_us > 0 and s.live and s.send is not None:
            demand += s.cost * 1000000 // s.interval_us
    return demand


def _stretch(interval_us, demand, avail):
    """interval_us * demand / avail, rounded up, with no int of 2^30 or more on the way:
    the ratio as a fraction of 4096 (demand is below _DEMAND_MAX), the product in two
    parts, and MAX_INTERVAL_US at most."""
    r = ((demand << 12) + avail - 1) // avail
    if r > _RATIO_MAX:  # over 64 times the budget: whole multiples are fine enough
        q = (demand + avail - 1) // avail
        return MAX_INTERVAL_US if interval_us > MAX_INTERVAL_US // q else interval_us * q
    q = interval_us >> 12
    if q and r > (MAX_INTERVAL_US - 1) // q:  # q * r >= MAX_INTERVAL_US (it may pass 2^30)
        return MAX_INTERVAL_US
    return q * r + (((interval_us & 4095) * r + 4095) >> 12)


# --- every tick (allocation-free; small frames: see docs/design.md) ---------------------

def run(ls, now):
    """Send what is due on one link, from ls.start on, while its budget lasts."""
    ls.wait = _WAIT_MAX_MS
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
        late = ticks_diff(now, s.due) + _SLACK_MS  # (early by as much as the loop's slack)
        if late < 0:
            if late < -2 * s.step_ms - 2:  # the clock jumped back: start again
                s.due = now
                ls.wait = 0
            elif -late + _SLACK_MS < ls.wait:
                ls.wait = -late + _SLACK_MS
            continue
        if not _send(ls, s):
            ls.wait = 1  # the budget will pay again soon
            return
        _until(ls, s)


def _until(ls, s):
    # A stream just sent: its next deadline may be the link's first.
    ms = ticks_diff(s.due, ls.now)
    if ms < ls.wait:
        ls.wait = ms if ms > 0 else 0


def _send(ls, s):
    """Send a due stream -> False when the link cannot pay for more now (it stays due)."""
    link = ls.link
    if not link.can_send(s.cost, RANK_BULK):
        return False
    before = link.tx_bytes
    held = link.tx_held + link.tx_dropped
    link.rank = RANK_BULK
    ok = link.endpoint.faults.run(s.send, link)  # a producer that raises is a fault: not sent
    link.rank = RANK_AUTO
    if ok is None and link.endpoint.faults.error is not None:
        link.endpoint.faults.count(PRODUCER, s.msgid)
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
