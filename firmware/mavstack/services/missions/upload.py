"""The upload of a plan: Upload, the Transfer (transfer.py) with the window of an upload
under way. MISSION_COUNT (or the seed's MISSION_WRITE_PARTIAL_LIST) -> MISSION_REQUEST_INT
per item (MISSION_REQUEST to a ground station of the seed's messages) -> MISSION_ACK.
Items go straight into the store's staging slot, in whatever order they come, and
replace the plan only once all are in. Requests fly several at a time (up to `window`
ahead); what is missing is asked again at once when three later items came without it,
else once a retransmission timeout from the measured round trip is up; a peer that
serves requests only in order is noticed and asked one item at a time. An item or
MISSION_COUNT sent before the frame that started this upload (held back by the link) is
ignored. Nothing here allocates: the window is a bit mask and a list made once.
Reference: docs/services/missions.md.
"""
import gc

from ...compat import const, ticks_add, ticks_diff
from ...link import RANK_FILL
from . import items as mission_items
from .transfer import IDLE, UPLOAD, Transfer

# Loading a module from a .mpy leaves the loader's garbage between the code it kept:
# collect it now, so that what comes next finds room on a small heap.
gc.collect()

_MSG_REQUEST = const(40)
_MSG_REQUEST_INT = const(51)
_MSG_ITEM_INT = const(73)
_ACCEPTED = const(0)
_FAST = const(3)  # items asked after a missing one that came without it: ask it again
# A request, MAVLink 2, for the link's budget: header 10, payload 5, CRC 2.
REQUEST_BYTES = const(17)


class Upload(Transfer):
    """The transfer under way, with the window of an upload. During an upload, seq is the
    first item not in yet (the window's base) and end its last item."""

    def __init__(self, missions, window=8, retry_ms=250, rto_min=20, rto_max=1000, backoffs=5):
        Transfer.__init__(self, missions)
        self.window = window if 0 < window <= 16 else 8  # the bit masks stay below 2^16
        self.asked = [0] * self.window  # when item seq was last asked for: slot seq % window
        self.retry_ms = retry_ms
        self.rto_min = rto_min
        self.rto_max = rto_max
        self.backoffs = backoffs
        self.first = 0  # first item of this upload (a partial one starts later)
        self.top = 0  # first item not asked for yet
        self.held = 0  # bit i: item seq + i is in
        self.again = 0  # bit i: item seq + i was asked more than once (no RTT sample)
        self.after = 0  # items asked after seq's last request that came without it
        self.mark = 0  # the first item asked after seq's last request
        self.cursor = 0  # the item after the last new one received: where the peer stands
        self.reach = 0  # the item after the furthest one received since the transfer began
        self.strict = False  # the peer serves requests only in order (see tick)
        self.probe = -1  # the item asked below the window after a slide (see _slide), -2: no more
        self.probe_seq = 0  # seq when it was asked ...
        self.probe_held = 0  # ... and held (two ints: seq << 16 | held passes 2^30)
        self.srtt8 = -1  # smoothed round trip, ms * 8 (-1: no sample yet)
        self.var4 = 0  # its mean deviation, ms * 4
        self.rto = retry_ms
        self.heard = 0  # ticks of the last move of seq: the timer runs from it too
        self.tries = 0  # expiries since the last new item
        self.current = -1  # the item sent with current=1, -2: keep the current one
        self.origin = 0  # packet sequence number of the frame that started the upload
        self.look = 0  # ticks at which the service's tick next looks at this upload

    def upload(self, link, store, first, keep):
        """Ask link's sender for items first .. end of a plan of count items (the caller
        sets count and end; keep: items of the plan in force copied first)."""
        if not store.begin(keep):
            self.m.reply(link, self.m.unsaved(), store.mission_type)
            return
        if self.start(link, UPLOAD, store):
            self.reach = 0
        self.origin = link.rx.seq
        self.first = self.seq = self.top = self.cursor = first
        self.mark = first + 1
        self.held = self.again = self.after = self.tries = 0
        self.strict = False
        self.probe = -1
        self.current = -1 if first == 0 and keep == 0 else -2
        self.srtt8 = -1
        self.rto = self.retry_ms
        self.heard = self.sent
        self._fill(self.sent)

    def late_count(self, link, p, count):
        """During its upload, a MISSION_COUNT the uploader sent before the one that
        started it (held back by the link), or a copy of that one once items are in:
        not a new upload."""
        if not self.holds(link, UPLOAD):
            return False
        return sent_before(link.rx, self.origin) or (
            self.first == 0 and count == self.count and (self.seq > 0 or self.held != 0)
            and (p[4] if self.m.has_type else 0) == self.store.mission_type)

    # --- asking -------------------------------------------------------------------
    def _fill(self, now):
        """Ask for items not asked yet, as far as the window goes. The first missing item
        is always asked (a reply, at the link's reply rank); the ones ahead of it are
        bulk: they wait while the link's byte budget has no room at RANK_FILL (streams
        and replies go first)."""
        while self.top - self.seq < self.window and (
                self.top < self.end or (self.top == self.end and self.seq == self.end)):
            if self.top != self.seq and not self.link.can_send(REQUEST_BYTES, RANK_FILL):
                return
            self._send(self.top)
            self.asked[self.top % self.window] = now
            self.top += 1

    def _send(self, seq):
        """MISSION_REQUEST_INT (or MISSION_REQUEST) for item seq -> sent."""
        link = self.link
        off = link.begin()
        buf = link.txbuf
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        buf[off + 2] = self.peer >> 8
        buf[off + 3] = self.peer & 0xFF
        buf[off + 4] = self.store.mission_type
        return link.send(_MSG_REQUEST_INT if self.as_int else _MSG_REQUEST)

    def _again(self, seq, now):
        """Ask for item seq (in the window) once more; its round trip is not timed."""
        self._send(seq)  # not sent (no room): as good as lost, its time runs anyway
        self.asked[seq % self.window] = now
        self.again |= 1 << (seq - self.seq)
        if seq == self.seq:
            self.after = 0
            self.mark = self.top

    # --- items --------------------------------------------------------------------
    def item(self, link, p, seq):
        """Item seq from the uploader, of the plan type under upload."""
        if seq >= self.top or seq < self.first or (
                link.rx.late_at == link.rx.frames and sent_before(link.rx, self.origin)):
            return  # not asked for, or sent before this upload began (see above): ignored
        if seq < self.seq or self.held >> (seq - self.seq) & 1:
            # A copy of one already in: late copies must not move the cursor back, but
            # one a peer that serves in order sent when asked does (it stands there). The
            # answer to the probe with nothing else in since: it serves in order.
            if not self.strict and seq == self.probe:
                self.strict = self.probe_seq == self.seq and self.probe_held == self.held
                self.probe = -1 if self.strict else -2
            if self.strict:
                self.cursor = seq + 1
                self._ask_next(self.m.ep.now)
            return
        self.cursor = seq + 1
        if self._take(link, p, seq):
            self._got(seq, self.m.ep.now)
            if self.state == UPLOAD and (self.top < self.end and self.top - self.seq < self.window
                                         or ticks_diff(self.look, ticks_add(self.m.ep.now, self.rto)) > 0):
                # Items do not wake the tick (missions/__init__.py): it is woken when
                # requests wait for the budget, or when the retry may now be due before
                # the look it last set (a shorter round trip).
                self.m.ep.wake(self.m)

    def _take(self, link, p, seq):
        """Check and stage item seq -> True; else the upload ends with the error."""
        is_int = link.rx.msgid == _MSG_ITEM_INT
        if not is_int:
            self.as_int = False  # it speaks the seed's messages: ask in its terms
        result = self._stage(p, seq, is_int)
        if result != _ACCEPTED:
            self.state = IDLE
            self.m.reply(link, result, self.store.mission_type)
            return False
        if p[35] == 1 and self.current != -2 and seq > self.current:
            self.current = seq
        return True

    def _got(self, seq, now):
        """Item seq is in: time the round trip, slide the window, ask on."""
        bit = seq - self.seq
        if seq >= self.reach:  # progress: what a restart asks for again is none
            self.reach = seq + 1
            self.progress = now
            self.moved = True
        self.tries = 0
        self._sample(-1 if self.again >> bit & 1 else ticks_diff(now, self.asked[seq % self.window]))
        self.held |= 1 << bit
        if bit == 0:
            self._slide(now)
        elif self.strict:
            self._ask_next(now)
        elif seq >= self.mark:
            self.after += 1  # asked after the first missing one, and here before it
            if self.after >= _FAST:
                self._again(self.seq, now)

    def _slide(self, now):
        self.heard = now
        while self.held & 1:
            self.held >>= 1
            self.again >>= 1
            self.seq += 1
        if self.seq > self.end:
            self._finish()
            return
        # Items in that were asked after the new first missing one: all those after it,
        # unless it was asked again (then only those asked since: none in yet).
        self.mark = self.top if self.again & 1 else self.seq + 1
        h = self.held >> (self.mark - self.seq)  # (held has no bits past the window)
        i = 0
        while h:  # its bits set, one pass each (in order, none)
            h &= h - 1
            i += 1
        self.after = i
        if self.strict:
            self._ask_next(now)
            return
        self._fill(now)
        if self.after >= _FAST:
            self._again(self.seq, now)
        if self.cursor < self.seq and self.probe != -2:
            # The peer's last item was one asked again, before the window: a peer that
            # serves only in order stands there and refuses the window. Ask that item
            # too; if it alone comes back, the peer is one (found within a round trip,
            # not after two expiries of the timer, which a ground station's own timeout
            # may not wait); if the window's items come first, it is not: no more probes.
            self.probe = self.cursor
            self.probe_seq = self.seq
            self.probe_held = self.held
            self._send(self.cursor)

    def _stage(self, p, seq, is_int):
        """Check item seq and write its record into the staging slot -> MAV_MISSION_RESULT."""
        result = mission_items.check(self.m, p, is_int, seq)
        if result == _ACCEPTED and not self.store.put(seq, self.m.rec):
            return self.m.unsaved()
        return result

    def _finish(self):
        """All items are in: the new plan replaces the one in force, and the uploader is told."""
        m = self.m
        self.state = IDLE
        store = self.store
        result = m.commit(store, self.count)
        if result == _ACCEPTED:
            m.done_link = self.link  # a repeat of the last item is answered (rare.py)
            m.done_key = self.peer << 8 | store.mission_type
            m.done_seq = self.end
            m.plan_changed(store, 0 if self.current == -1 else self.current)  # -2: keep
        m.ack(self.link, self.peer, result, store.mission_type)

    # --- time ---------------------------------------------------------------------
    def tick(self, now):
        """An upload under way: ask again for what is overdue -> ms to the next look."""
        if self.top == self.seq and not self.strict:
            self._fill(now)  # nothing asked yet: the link had no room
            return 1
        if ticks_diff(now, self.heard) < self.rto or not (
                self.strict or ticks_diff(now, self.asked[self.seq % self.window]) >= self.rto):
            return self._next_look(now)
        if self.tries < self.backoffs:  # back off
            self.tries += 1
            self.rto = self.rto * 2 if self.rto * 2 < self.rto_max else self.rto_max
        if self.strict or (self.cursor < self.seq and self.tries > 1):
            # Twice nothing came while the peer stands before the first missing item
            # (once may be a late item): it serves only in order. One request at a
            # time now, each for the item after the last one it sent.
            self.strict = True
            self._ask_next(now)
            return self._next_look(now)
        # Ask again for each missing item asked a while ago (rto / 4: the first missing
        # one, and those asked with it).
        seq = self.seq
        while seq < self.top:
            if (not self.held >> (seq - self.seq) & 1
                    and ticks_diff(now, self.asked[seq % self.window]) >= self.rto >> 2):
                self._again(seq, now)
            seq += 1
        return self._next_look(now)

    def _next_look(self, now):
        # Items not yet asked for wait on the budget: soon. Else when the retry is due.
        if self.top < self.end and self.top - self.seq < self.window:
            return 1
        since = ticks_diff(now, self.heard)
        if not self.strict and ticks_diff(now, self.asked[self.seq % self.window]) < since:
            since = ticks_diff(now, self.asked[self.seq % self.window])
        return self.rto - since if since < self.rto else 1

    def _ask_next(self, now):
        """Serving in order: ask for the item after the last one the peer sent, or for
        the first missing one if that comes first (ahead of it the peer answers nothing)."""
        seq = self.cursor if self.cursor < self.seq else self.seq
        if seq > self.end:
            return
        self.heard = now
        if seq >= self.seq:
            if seq < self.top:
                self.again |= 1  # asked before: its round trip is not timed
            self.top = seq + 1 if seq >= self.top else self.top
            self.asked[seq % self.window] = now
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



def sent_before(rx, origin):
    """The frame in hand (rx: its link's parser) was sent before the frame numbered
    origin that started the upload (see above)."""
    return rx.late_at == rx.frames and (rx.seq - origin) & 0xFF >= 128
