"""The one mission transfer under way: an upload, a download or a partial list the
vehicle pushes, and the ground station it is with. Its states are defined here, and
its methods are the rules of the slot: whether a request may start beside it or take
it over (may_start, end_for), starting it, cancelling it (its ground station told) and
its progress. It also serves the download (MISSION_REQUEST_LIST -> MISSION_COUNT, each
MISSION_REQUEST(_INT) answered from flash). upload.py's Upload extends it with the
upload's window; the service makes that one object at start-up (Missions.transfer),
so that nothing is made per transfer. Reference: docs/services/missions.md.
"""
import gc

from ...compat import const
from ...fields import LOCAL_FRAMES, unfix
from ...kernels import copy

# Loading a module from a .mpy leaves the loader's garbage between the code it kept:
# collect it now, so that what comes next finds room on a small heap.
gc.collect()

IDLE = const(0)
UPLOAD = const(1)
DOWNLOAD = const(2)
PUSH = const(3)  # a partial list: the vehicle sends the items
# How a request bears on the plan (bits of the service's table of requests): CHANGE
# changes it (operator control needed), EVERY may name MAV_MISSION_TYPE_ALL (255).
CHANGE = const(8)
EVERY = const(16)

_MSG_ITEM = const(39)
_MSG_REQUEST_LIST = const(43)
_MSG_COUNT = const(44)
_MSG_REQUEST_INT = const(51)
_MSG_ITEM_INT = const(73)
_ERROR = const(1)  # MAV_MISSION_RESULT
_UNSUPPORTED = const(3)
_INVALID_SEQUENCE = const(13)
_DENIED = const(14)
_OPERATION_CANCELLED = const(15)
_TYPE_MISSION = const(0)


class Transfer:
    def __init__(self, missions):
        self.m = missions  # the service: its stores, settings and replies
        self.state = IDLE
        self.link = None
        self.peer = 0  # its sysid << 8 | compid
        self.store = None  # the MissionStore of its plan type
        self.count = 0  # items in the plan once this upload is done
        self.seq = 0  # the next item: to come in (upload), to push, never served (download)
        self.end = 0  # the last item of this transfer
        self.as_int = True  # ask / push with the _INT messages (else the seed's)
        self.sent = 0  # ticks of the last push
        self.progress = 0  # ticks of its last progress (or of its start)
        self.fresh = True  # the next start begins a transfer (not its peer's restart)
        self.moved = False  # it has made progress since it (re)started
        self.share = False  # the request in hand is served beside another's download
        self.credit = 0  # bytes the push may send now

    def is_peer(self, link):
        """The frame in hand (on link) comes from the transfer's ground station."""
        rx = link.rx
        return link is self.link and rx.sysid << 8 | rx.compid == self.peer

    def holds(self, link, state):
        """A transfer in state is under way with the sender of the frame in hand."""
        return self.state == state and self.is_peer(link)

    def may_start(self, link, how):
        """May link's request (how: its CHANGE, EVERY bits) start beside or over this one?"""
        state = self.state
        if state == IDLE or self.is_peer(link):
            return True
        if how & CHANGE:  # the plan changes: reads give way, and an upload that is not moving
            return state != UPLOAD or not self.moved
        # A download goes beside another's download or partial read; a partial read
        # (which the vehicle pushes) takes the slot from a download, not from another push.
        return state == DOWNLOAD or (state == PUSH and link.rx.msgid == _MSG_REQUEST_LIST)

    def end_for(self, link, how):
        """What becomes of this transfer now that link's request starts: its own peer
        starts over (its progress clock runs on); another's is cancelled where the plan
        changes, and left to go on where a download starts beside it."""
        self.share = False
        if self.state == IDLE:
            self.fresh = True
        elif self.is_peer(link):
            self.fresh = False
        elif how & CHANGE:
            self.cancel()
            self.fresh = True
        elif link.rx.msgid == _MSG_REQUEST_LIST:
            self.share = True  # served beside it: the slot stays with the other
            return
        else:
            self.fresh = True  # a partial read takes the slot; the download goes on unlocked
        self.state = IDLE

    def start(self, link, state, store):
        """A transfer with link's sender begins (the caller sets seq, end) -> True when
        it is a new one, False when its peer starts over (it keeps how far it had come)."""
        rx = link.rx
        fresh = self.fresh
        self.state = state
        self.link = link
        self.peer = rx.sysid << 8 | rx.compid
        self.store = store
        self.as_int = self.m.has_int and rx.version == 2
        self.sent = self.m.ep.now
        if fresh:
            self.progress = self.sent
            self.seq = 0
        self.fresh = True
        self.moved = False
        self.m.done_seq = -1  # the upload that completed last is answered no more
        return fresh

    def cancel(self):
        """This transfer ends unfinished (an upload's staged items are dropped); its
        ground station is told."""
        self.state = IDLE
        link = self.link
        self.m.ack(link, self.peer, _OPERATION_CANCELLED if link.version == 2 else _ERROR,
                   self.store.mission_type)

    def on_ack(self, link, p):
        """MISSION_ACK: the peer ends its download, or cancels its upload (nothing is stored)."""
        if (self.m.ep.for_us(p[0], p[1]) and self.state != IDLE and self.is_peer(link)
                and (p[3] if self.m.has_type else 0) == self.store.mission_type):
            self.state = IDLE

    # --- the download -------------------------------------------------------------
    def on_request_list(self, link, p):
        store = self.m.store_for(link, p)
        if store is None:
            return
        if store.count and not self.share:
            self.start(link, DOWNLOAD, store)
            self.end = store.count - 1
        off = link.begin()
        buf = link.txbuf
        buf[off] = store.count & 0xFF
        buf[off + 1] = store.count >> 8
        buf[off + 2] = link.rx.sysid
        buf[off + 3] = link.rx.compid
        buf[off + 4] = store.mission_type
        store.put_plan_id(buf, off + 5)  # opaque_id, where the dialect has it
        link.send(_MSG_COUNT)

    def on_request(self, link, p):
        """MISSION_REQUEST_INT, answered with MISSION_ITEM_INT (the seed's MISSION_REQUEST
        with MISSION_ITEM) unless another ground station's upload is under way."""
        if not self.m.ep.for_us(p[2], p[3]):
            return
        mt = p[4] if self.m.has_type else 0
        if self.state == UPLOAD:  # reads wait for an upload; its own uploader knows better
            if not self.is_peer(link):
                self.m.reply(link, _DENIED, mt)
            return
        store = self.m.stores[mt] if mt < 3 and (mt == 0 or link.version == 2) else None
        seq = p[0] | p[1] << 8
        if store is None:
            self.m.reply(link, _UNSUPPORTED, mt)
        else:
            self._serve(link, store, seq)

    def _serve(self, link, store, seq):
        if seq >= store.count:
            if self.holds(link, DOWNLOAD):
                self.state = IDLE
            self.m.reply(link, _INVALID_SEQUENCE, store.mission_type)
            return
        self.send_item(link, store, seq, link.rx.msgid == _MSG_REQUEST_INT)
        if not self.holds(link, DOWNLOAD):
            return  # served beside the transfer under way, or with none
        if seq >= self.seq:
            self.seq = seq + 1  # a new item served: progress (a restart's repeats are not)
            self.progress = self.m.ep.now
        if seq == self.end:
            self.state = IDLE  # the last item: done, whether or not an ACK follows

    def send_item(self, link, store, seq, as_int):
        """Item seq of store to link's sender, as MISSION_ITEM_INT or the seed's MISSION_ITEM."""
        if not store.read(seq, self.m.rec):
            return
        off = self._item_into(link, seq, store.mission_type)
        if as_int:
            link.send(_MSG_ITEM_INT)
        else:  # x, y as float degrees (metres if local)
            unfix(link.txbuf, off + 16, self.m.rec[30] in LOCAL_FRAMES)
            unfix(link.txbuf, off + 20, self.m.rec[30] in LOCAL_FRAMES)
            link.send(_MSG_ITEM)

    def _item_into(self, link, seq, mt):
        """MISSION_ITEM_INT's payload in link.txbuf from record seq (in m.rec) -> its offset."""
        off = link.begin()
        buf = link.txbuf
        copy(buf, self.m.rec, off, 28)
        buf[off + 28] = seq & 0xFF
        buf[off + 29] = seq >> 8
        buf[off + 30] = self.m.rec[28]
        buf[off + 31] = self.m.rec[29]
        buf[off + 32] = link.rx.sysid
        buf[off + 33] = link.rx.compid
        buf[off + 34] = self.m.rec[30]
        buf[off + 35] = 1 if mt == _TYPE_MISSION and self.m.runner is not None and seq == self.m.runner.current else 0
        buf[off + 36] = self.m.rec[31]
        buf[off + 37] = mt
        return off
