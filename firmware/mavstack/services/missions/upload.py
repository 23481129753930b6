"""The upload of a plan, for missions.py: MISSION_COUNT (or the seed's
MISSION_WRITE_PARTIAL_LIST) -> MISSION_REQUEST_INT per item (MISSION_REQUEST to a ground
station that speaks MAVLink 1 or answers with the seed's MISSION_ITEM) -> MISSION_ACK.
Items go straight into the store's staging slot (mission_store.py) in whatever order
they come, and replace the plan only once all are in; any failure leaves the stored
plan as it was.

Requests fly several at a time, so that a lost frame costs one item, not a round trip
of waiting: up to `window` items are asked ahead, the first missing one stays asked
while the later ones come, and only what is missing is asked again:
- at once, when three items asked after a missing one have come without it (frames
  keep their order on a radio or UDP link: it, or its request, was lost);
- when its time is up: a retransmission timeout from the measured round trip (request
  to item: smoothed RTT + 4 x its deviation, or + RTT / 4 if more; no sample from an
  item asked twice) since it was asked and since it became the first missing one
  (items asked together queue behind each other: a later one is late, not lost),
  between rto_min and rto_max, doubled on each expiry without progress (at most
  `backoffs` times in a row). Before the first sample it is retry_ms.
The last item is asked for only once all the others are in: a ground station may take
that request as the end of its upload (MAVProxy stops answering after it). Some ground
stations serve requests only in order: MAVSDK answers a request for the item after the
last one it sent, or for an earlier one, and ignores requests ahead of that; after a
lost frame it stands behind the items asked ahead, and it counts repeated requests
against its own retries. (Where its request was lost it ignores those after it; asking
again for all that is missing, in order, serves it.) When time is up twice in a row
while the item after the last one received is below the first missing one, the peer is
taken to be such a one: from then on the upload asks one item at a time, always the
one after the last the peer sent (held ones too), as a lock-step upload would.
An upload is cancelled (OPERATION_CANCELLED, ERROR to MAVLink 1) only when no new item
has come for the service's timeout_ms (missions.py), however many requests that took.

MISSION_ITEM(_INT) names no transfer: a copy of an earlier upload's item that a link
held back (a radio's retries, a reordering router) would pass for this upload's item of
the same seq. Every frame carries its sender's packet sequence number, counted up per
frame (routers pass it on). An item is ignored (and, if missing, asked for again) when
it is both late, numbered before the newest frame its sender has sent (parser.late_at),
and numbered before the frame that started this upload: sent before the upload began.
Late alone is not enough: a ground station started again numbers from 0, and all its
frames read as late until its numbers pass its old ones (mavctl is a new process each
run). missions.py likewise ignores such a MISSION_COUNT during the upload. Between
transfers nothing tells a held-back MISSION_COUNT from a restarted station's first one.

Nothing here allocates: the window is a bit mask (bit i: item base + i is in) and a
list of request times made once; times are ticks_ms values (small ints) and their
differences, 32-bit clean. Each function keeps within 11 words of locals and stack.
"""
import gc

from ...compat import const, ticks_diff
from ...link import RANK_FILL
from . import items as mission_items

# Loading a module from a .mpy leaves the loader's garbage between the code it kept:
# collect it now, so that what comes next finds room on a small heap.
gc.collect()

_MSG_REQUEST = const(40)
_MSG_REQUEST_INT = const(51)
_MSG_ITEM_INT = const(73)
_ACCEPTED = const(0)
_ERROR = const(1)
_IDLE = const(0)
_UPLOAD = const(1)
_FAST = const(3)  # items asked after a missing one that came without it: ask it again
# A request, MAVLink 2, for the link's budget: header 10, payload 5, CRC 2.
REQUEST_BYTES = const(17)


class Upload:
    def __init__(self, m, window=8, retry_ms=250, rto_min=20, rto_max=1000, backoffs=5):
        self.m = m  # the missions service: the transfer's link, peer and store are its
        self.window = window if 0 < window <= 16 else 8  # the bit masks stay below 2^16
        self.sent = [0] * self.window  # when item seq was last asked for: slot seq % window
        self.retry_ms = retry_ms
        self.rto_min = rto_min
        self.rto_max = rto_max
        self.backoffs = backoffs
        self.first = 0  # first item of this upload (a partial one starts later)
        self.end = 0  # its last item
        self.base = 0  # first item not in yet
        self.top = 0  # first item not asked for yet
        self.held = 0  # bit i: item base + i is in
        self.again = 0  # bit i: item base + i was asked more than once (no RTT sample)
        self.after = 0  # items asked after base's last request that came without it
        self.mark = 0  # the first item asked after base's last request
        self.cursor = 0  # the item after the last new one received: where the peer stands
        self.reach = 0  # the item after the furthest one received since the transfer began
        self.strict = False  # the peer serves requests only in order (see tick)
        self.srtt8 = -1  # smoothed round trip, ms * 8 (-1: no sample yet)
        self.var4 = 0  # its mean deviation, ms * 4
        self.rto = retry_ms
        self.heard = 0  # ticks of the last move of base: the timer runs from it too
        self.tries = 0  # expiries since the last new item
        self.current = -1  # the item sent with current=1, -2: keep the current one
        self.origin = 0  # packet sequence number of the frame that started the upload

    def start(self, link, store, first, keep):
        """Ask for items first .. m.t_end of a plan of m.t_count items (keep: items of the
        plan in force copied first)."""
        if not store.begin(keep):
            self.m._storage_failed(link, store)
            return
        self.m._start(link, _UPLOAD, store)
        self.origin = link.rx.seq
        self.first = self.base = self.top = self.cursor = self.m.t_seq = first
        self.mark = first + 1
        self.end = self.m.t_end
        self.held = self.again = self.after = self.tries = 0
        self.strict = False
        self.current = -1 if first == 0 and keep == 0 else -2
        self.srtt8 = -1
        self.rto = self.retry_ms
        self.heard = self.m.ep.now
        self._fill(self.m.ep.now)

    # --- asking -------------------------------------------------------------------
    def _fill(self, now):
        """Ask for items not asked yet, as far as the window goes. The first missing item
        is always asked (a reply, at the link's reply rank); the ones ahead of it are
        bulk: they wait while the link's byte budget has no room at RANK_FILL (streams
        and replies go first)."""
        while self.top - self.base < self.window and (
                self.top < self.end or (self.top == self.end and self.base == self.end)):
            if self.top != self.base and not self.m.t_link.can_send(REQUEST_BYTES, RANK_FILL):
                return
            self._send(self.top)
            self.sent[self.top % self.window] = now
            self.top += 1

    def _send(self, seq):
        """MISSION_REQUEST_INT (or MISSION_REQUEST) for item seq -> sent."""
        m = self.m
        link = m.t_link
        off = link.begin()
        buf = link.txbuf
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        buf[off + 2] = m.t_peer >> 8
        buf[off + 3] = m.t_peer & 0xFF
        buf[off + 4] = m.t_store.mission_type
        return link.send(_MSG_REQUEST_INT if m.t_int else _MSG_REQUEST)

    def _again(self, seq, now):
        """Ask for item seq (in the window) once more; its round trip is not timed."""
        self._send(seq)  # not sent (no room): as good as lost, its time runs anyway
        self.sent[seq % self.window] = now
        self.again |= 1 << (seq - self.base)
        if seq == self.base:
            self.after = 0
            self.mark = self.top

    # --- items --------------------------------------------------------------------
    def item(self, link, p, seq):
        """Item seq from the uploader, of the plan type under upload."""
        if seq >= self.top or seq < self.first or sent_before(link.rx, self.origin):
            return  # not asked for, or sent before this upload began (see above): ignored
        if seq < self.base or self.held >> (seq - self.base) & 1:
            # A copy of one already in: late copies must not move the cursor back, but
            # one a peer that serves in order sent when asked does (it stands there).
            if self.strict:
                self.cursor = seq + 1
                self._ask_next(self.m.ep.now)
            return
        self.cursor = seq + 1
        if self._take(link, p, seq):
            self._got(seq, self.m.ep.now)

    def _take(self, link, p, seq):
        """Check and stage item seq -> True; else the upload ends with the error."""
        is_int = link.rx.msgid == _MSG_ITEM_INT
        if not is_int:
            self.m.t_int = False  # it speaks the seed's messages: ask in its terms
        result = _stage(self.m, p, seq, is_int)
        if result != _ACCEPTED:
            self.m.state = _IDLE
            self.m._reply(link, result, self.m.t_store.mission_type)
            return False
        if p[35] == 1 and self.current != -2 and seq > self.current:
            self.current = seq
        return True

    def _got(self, seq, now):
        """Item seq is in: time the round trip, slide the window, ask on."""
        bit = seq - self.base
        if seq >= self.reach:  # progress: what a restart asks for again is none
            self.reach = seq + 1
            self.m.t_progress = now
            self.m.t_moved = True
        self.tries = 0
        self._sample(-1 if self.again >> bit & 1 else ticks_diff(now, self.sent[seq % self.window]))
        self.held |= 1 << bit
        if bit == 0:
            self._slide(now)
        elif self.strict:
            self._ask_next(now)
        elif seq >= self.mark:
            self.after += 1  # asked after the first missing one, and here before it
            if self.after >= _FAST:
                self._again(self.base, now)

    def _slide(self, now):
        self.heard = now
        while self.held & 1:
            self.held >>= 1
            self.again >>= 1
            self.base += 1
        self.m.t_seq = self.base
        if self.base > self.end:
            self._finish()
            return
        # Items in that were asked after the new first missing one: all those after it,
        # unless it was asked again (then only those asked since: none in yet).
        self.mark = self.top if self.again & 1 else self.base + 1
        self.after = 0
        i = self.mark - self.base
        while i < self.window:
            self.after += self.held >> i & 1
            i += 1
        if self.strict:
            self._ask_next(now)
            return
        self._fill(now)
        if self.after >= _FAST:
            self._again(self.base, now)

    def _finish(self):
        m = self.m
        m.state = _IDLE
        store = m.t_store
        result = m._commit(store, m.t_count)
        if result == _ACCEPTED:
            m.done_link = m.t_link
            m.done_key = m.t_peer << 8 | store.mission_type
            m.done_seq = self.end
            m._plan_changed(store, 0 if self.current == -1 else self.current)  # -2: keep
        m._ack(m.t_link, m.t_peer, result, store.mission_type)

    # --- time ---------------------------------------------------------------------
    def tick(self, now):
        if self.strict:
            if ticks_diff(now, self.heard) >= self.rto:
                self._back_off()
                self._ask_next(now)
        elif self.top == self.base:
            self._fill(now)  # nothing asked yet: the link had no room
        elif (ticks_diff(now, self.sent[self.base % self.window]) >= self.rto
              and ticks_diff(now, self.heard) >= self.rto):
            self._back_off()
            if self.cursor < self.base and self.tries > 1:
                # Twice nothing came while the peer stands before the first missing
                # item (once may be a late item): it serves only in order. One request
                # at a time now, each for the item after the last one it sent.
                self.strict = True
                self._ask_next(now)
            else:
                self._resend(now)

    def _back_off(self):
        if self.tries < self.backoffs:
            self.tries += 1
            self.rto = self.rto * 2 if self.rto * 2 < self.rto_max else self.rto_max

    def _resend(self, now):
        """Ask again for each missing item asked a while ago (rto / 4: the first missing
        one, and those asked with it)."""
        seq = self.base
        while seq < self.top:
            if (not self.held >> (seq - self.base) & 1
                    and ticks_diff(now, self.sent[seq % self.window]) >= self.rto >> 2):
                self._again(seq, now)
            seq += 1

    def _ask_next(self, now):
        """Serving in order: ask for the item after the last one the peer sent, or for
        the first missing one if that comes first (ahead of it the peer answers nothing)."""
        seq = self.cursor if self.cursor < self.base else self.base
        if seq > self.end:
            return
        self.heard = now
        if seq >= self.base:
            if seq < self.top:
                self.again |= 1  # asked before: its round trip is not timed
            self.top = seq + 1 if seq >= self.top else self.top
            self.sent[seq % self.window] = now
        self._send(seq)

    def _sample(self, ms):
        """One round trip, in ms, into the smoothed RTT and its deviation, and the
        re-request time from them: srtt + 4 x deviation, and at least a quarter more
        than srtt (a steady round trip wears the deviation down to nothing, and an item
        due just then is not lost), back-off dropped. -1: an item asked more than once
        came, which times nothing: the backed-off time is halved back toward that (as it
        was doubled on each expiry), so a queue of re-requests longer than the
        re-request time cannot keep growing, nor one lost frame keep it long."""
        if ms > self.rto_max:
            ms = self.rto_max
        if ms < 0:
            pass
        elif self.srtt8 < 0:
            self.srtt8 = ms << 3
            self.var4 = ms << 1
        else:
            ms -= self.srtt8 >> 3
            self.srtt8 += ms
            self.var4 += (ms if ms >= 0 else -ms) - (self.var4 >> 2)
        t = self.srtt8 >> 3
        t += self.var4 if self.var4 > t >> 2 else t >> 2
        if self.srtt8 < 0:
            t = self.retry_ms
        if ms < 0 and t < self.rto >> 1:
            t = self.rto >> 1
        self.rto = self.rto_min if t < self.rto_min else (self.rto_max if t > self.rto_max else t)

def _stage(m, p, seq, is_int):
    """Check item seq and write its record into the staging slot -> MAV_MISSION_RESULT."""
    result = mission_items.check(m, p, is_int, seq)
    if result == _ACCEPTED and not m.t_store.put(seq, m._rec):
        return m._unsaved()
    return result


def sent_before(rx, origin):
    """The frame in hand (rx: its link's parser) was sent before the frame numbered
    origin that started the upload (see above)."""
    return rx.late_at == rx.frames and (rx.seq - origin) & 0xFF >= 128
