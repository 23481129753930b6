"""Mission protocol, vehicle side: mission, fence and rally plans, uploaded, downloaded,
cleared, partially read and written, with the current item and its progress. This
module is the service: it takes the messages, keeps the one transfer under way (who
has it, and whether another ground station may take it over), serves downloads and
sends MISSION_CURRENT. Beside it: mission_upload.py (the upload: windowed requests,
re-requests from the measured round trip), mission_items.py (what an item must hold,
and the seed's float degrees), mission_store.py (plans in flash), mission_rare.py
(partial lists, MISSION_CLEAR_ALL, MISSION_SET_CURRENT and items outside an upload,
loaded when the first of them comes, at start-up on a board that locks its heap: a
ground station seldom sends them, and a small board's heap holds that code only once
it is used), mission_runner.py (what the application flies).

Download: MISSION_REQUEST_LIST -> MISSION_COUNT, then each MISSION_REQUEST_INT or
MISSION_REQUEST answered from flash; the ground station's final ACK is welcome, not
needed. Fence and rally need MAVLink 2 (mission_type is an extension field).

One transfer holds the slot at a time (the upload, download or partial read under way,
with its ground station), and none is blocked for long by another ground station:
- an upload (or partial write, or clear) is refused (MAV_MISSION_DENIED) while another
  ground station's upload is under way and moving; but one from a ground station
  allowed to change the plan (ep.allows: the one in control, or anyone when operator
  control is off) takes over from another's download or partial read, or from an
  upload that has had no new item since it (re)started. The ground station that loses
  its transfer gets MISSION_ACK OPERATION_CANCELLED (ERROR on MAVLink 1);
- downloads are reads: they need no control and never take anything over from
  another ground station's transfer. While another ground station downloads, a
  MISSION_REQUEST_LIST is answered beside it and its items served (the slot stays
  with the first); only during another's upload are reads refused;
- the same ground station starting again restarts its own transfer;
- a transfer that has made no progress (a new item in, or a new item served) for
  timeout_ms is cancelled the same way. Restarts are not progress: re-sending
  MISSION_REQUEST_LIST or MISSION_COUNT does not hold a transfer against others.

Frames are written byte by byte at the payload offsets, so the same code serves the
seed dialect (no MISSION_ITEM_INT, no extension fields) and dialects whose MISSION_COUNT,
MISSION_ACK and MISSION_CURRENT carry plan ids (opaque_id): the encoder cuts each
payload to the length the dialect gives it. Nothing here allocates once a transfer
has started, on a 32-bit board too (plan ids are written as bytes). Handlers are split
into short functions: MicroPython puts a frame of more than 11 words (locals + stack)
on the heap.

    missions = ep.services["missions"]
    missions.stores[0|1|2]      the MissionStore of each plan type (None for a capacity of
                                0: a board without geofence or rally points)
    missions.runner             mission_runner.MissionRunner, what the application flies
                                (None on a board with MISSION_RUNNER = False: plans are
                                kept and served, MISSION_START is UNSUPPORTED)
    missions.upload             mission_upload.Upload (its window and round-trip timer)
    missions.allow(command, need=0)   a MAV_CMD the application flies (need: _P*/_POS bits)
    missions.on_guided = fn(link, payload, is_int) -> MAV_MISSION_RESULT   the application's
                                handler of a MISSION_ITEM(_INT) with current 2 (go there) or 3
                                (change altitude); None: such items are taken as plan items
"""
import gc

from ...compat import const, ticks_diff, ticks_add
from ...fields import u16
from ...kernels import copy
from ...units import LOCAL_FRAMES, unfix
from .store import MissionStore, RECORD_SIZE
from .upload import Upload, sent_before

USES = ("streams", "status", "geography")  # who sends MISSION_CURRENT; the mode; the safety area


# Loading this module from a .mpy leaves the loader's garbage between the code it
# kept: collect it now, so that the class and tables below find room on a small heap.
gc.collect()

_MSG_REQUEST_PARTIAL_LIST = const(37)
_MSG_WRITE_PARTIAL_LIST = const(38)
_MSG_ITEM = const(39)
_MSG_REQUEST = const(40)
_MSG_SET_CURRENT = const(41)
_MSG_CURRENT = const(42)
_MSG_REQUEST_LIST = const(43)
_MSG_COUNT = const(44)
_MSG_CLEAR_ALL = const(45)
_MSG_ITEM_REACHED = const(46)
_MSG_ACK = const(47)
_MSG_REQUEST_INT = const(51)
_MSG_ITEM_INT = const(73)

# MAV_MISSION_RESULT
_ACCEPTED = const(0)
_ERROR = const(1)
_UNSUPPORTED = const(3)
_NO_SPACE = const(4)
_INVALID_SEQUENCE = const(13)
_DENIED = const(14)
_OPERATION_CANCELLED = const(15)
_SEVERITY_ERROR = const(3)  # MAV_SEVERITY (a constant here: a lean board loads no statustext)

_TYPE_MISSION = const(0)
_TYPE_ALL = const(255)
_STATE_NO_MISSION = const(1)  # MISSION_STATE, without a runner
_STATE_NOT_STARTED = const(2)

_IDLE = const(0)
_UPLOAD = const(1)
_DOWNLOAD = const(2)
_PUSH = const(3)  # download of a partial list: the vehicle sends the items

_CAP_MISSION_FLOAT = const(1)
_CAP_MISSION_INT = const(4)
_CAP_MISSION_FENCE = const(16384)
_CAP_MISSION_RALLY = const(32768)

_CURRENT_PERIOD_MS = const(1000)
# The requests about one plan, by msgid - 37: bits 0-2 the offset of target_system
# (mission_type is 2 bytes on), _CHANGE: it changes the plan (operator control needed).
# _EVERY: MAV_MISSION_TYPE_ALL (255) allowed (MISSION_CLEAR_ALL).
_CHANGE = const(8)
_EVERY = const(16)
_OPEN = (b"\x04"  # 37 MISSION_REQUEST_PARTIAL_LIST
         b"\x0c"  # 38 MISSION_WRITE_PARTIAL_LIST: 4 | _CHANGE
         b"\x00\x00\x00\x00"  # 39-42: not requests about a plan
         b"\x00"  # 43 MISSION_REQUEST_LIST
         b"\x0a")  # 44 MISSION_COUNT: 2 | _CHANGE
_NAMES = ("mission", "fence", "rally")  # also their files' names in storage


class Missions:
    NAME = "missions"
    CLOCK = False  # tells no time: a board with missions alone makes no ep.clock
    # Set on the instance where there is one (at start-up: no dict growth later).
    extra = None  # {command: need} the application added to the mission rules (allow)
    runner = None  # mission_runner.MissionRunner
    rare = None  # mission_rare.py, once loaded (see _on_rare)
    on_guided = None  # the application's guided go-to (see above)

    def __init__(self, storage, capacities=(500, 100, 20), frames=(0, 2, 3, 5, 6), retry_ms=250,
                 retries=5, timeout_ms=5000, jump_slots=16, commands=(), window=8, rto_min=20,
                 rto_max=1000):
        # (Few attributes: on a small heap a bigger instance dict may not find room.)
        self.stores = [None, None, None]
        for t in range(3):
            if capacities[t] or t == 0:
                self.stores[t] = MissionStore(storage, _NAMES[t], t, capacities[t])
        self.frames = frames
        self.timeout_ms = timeout_ms
        self.jump_slots = jump_slots
        for command in commands:
            self.allow(command)
        self._rec = bytearray(RECORD_SIZE)
        self.upload = Upload(self, window, retry_ms, rto_min, rto_max, retries)
        # The transfer under way (one at a time) and its peer.
        self.state = _IDLE
        self.t_link = None
        self.t_peer = 0  # its sysid << 8 | compid
        self.t_store = None
        self.t_count = 0  # items in the plan once this upload is done
        self.t_seq = 0  # the next item: to come in (upload), to push, never served (download)
        self.t_end = 0  # last item of this transfer
        self.t_int = True  # ask / push with the _INT messages (else the seed's)
        self.t_sent = 0  # ticks of the last push
        self.t_progress = 0  # ticks of its last progress (or of its start)
        self.t_fresh = True  # the next _start begins a transfer (not its peer's restart)
        self.t_moved = False  # it has made progress since it (re)started
        self.t_share = False  # the request in hand is served beside another's download
        self.t_credit = 0
        # The upload that completed last, to answer a repeat of its final item.
        self.done_link = None
        self.done_key = -1  # sysid << 16 | compid << 8 | mission_type
        self.done_seq = -1
        self._current_due = 0

    def allow(self, command, need=0):
        """Accept a MAV_CMD in missions (the application can fly it)."""
        if self.extra is None:
            self.extra = {}
        self.extra[command] = need

    # --- wiring -------------------------------------------------------------------
    def attach(self, ep):
        self.ep = ep
        stores = self.stores
        for s in stores:
            if s is not None and s.corrupt:
                ep.statustext(3, "Stored %s plan corrupt: cleared" % _NAMES[s.mission_type])  # MAV_SEVERITY_ERROR
        # MISSION_ITEM_INT and MISSION_REQUEST_INT are in today's dialect, not the seed's
        # (where id 51 is another message); mission_type is an extension field.
        self.has_int = ep.has(_MSG_ITEM_INT) and ep.fmt(_MSG_ITEM_INT).startswith("<ffffiif") \
            and ep.has(_MSG_REQUEST_INT) and ep.fmt(_MSG_REQUEST_INT).startswith("<HBB")
        self.has_type = (ep.dialect.CRC_LEN.get(_MSG_COUNT, 0) >> 16) >= 5
        item = self._on_item  # (a bound method is an object: one each, shared by two ids)
        request = self._on_request
        rare = self._on_rare
        for msgid, handler in ((_MSG_COUNT, self._on_count), (_MSG_WRITE_PARTIAL_LIST, rare),
                               (_MSG_ITEM, item), (_MSG_REQUEST_LIST, self._on_request_list),
                               (_MSG_REQUEST_PARTIAL_LIST, rare), (_MSG_REQUEST, request),
                               (_MSG_CLEAR_ALL, rare), (_MSG_SET_CURRENT, rare), (_MSG_ACK, self._on_ack)):
            ep.on(msgid, handler)
        ep.capabilities |= _CAP_MISSION_FLOAT
        if self.has_int:
            ep.on(_MSG_ITEM_INT, item)
            ep.on(_MSG_REQUEST_INT, request)
            ep.capabilities |= _CAP_MISSION_INT
        if self.has_type and stores[1] is not None:
            ep.capabilities |= _CAP_MISSION_FENCE
        if self.has_type and stores[2] is not None:
            ep.capabilities |= _CAP_MISSION_RALLY
        ep.producers[_MSG_CURRENT] = self.send_current
        self._current_due = ep.now
        self._current_changed = True

    # --- periodic work ------------------------------------------------------------
    def tick(self, now):
        state = self.state
        if state != _IDLE and ticks_diff(now, self.t_progress) >= self.timeout_ms:
            self._cancel()  # stale: the ground station went away, or only starts over
        elif state == _UPLOAD:
            self.upload.tick(now)
        elif state == _PUSH:
            self.rare.push(self, now)
        # On change; and once a second unless the streams service schedules it (it is
        # in the default streams there, and a ground station may change its rate).
        if self._current_changed or (
            ticks_diff(now, self._current_due) >= 0 and self.ep.services.get("streams") is None
        ):
            for link in self.ep.links:
                self.send_current(link)
            self._current_changed = False
            self._current_due = ticks_add(now, _CURRENT_PERIOD_MS)

    def current_changed(self):
        """Send MISSION_CURRENT on the next tick (the runner calls this)."""
        self._current_changed = True

    # --- the transfer under way ---------------------------------------------------
    def _is_peer(self, link):
        rx = link.rx
        return link is self.t_link and rx.sysid << 8 | rx.compid == self.t_peer

    # mission_type is an extension field: where the dialect has none it reads as 0 (the
    # payload view holds stale bytes past a message's length), hence `if self.has_type`.

    def _store(self, link, p):
        """Checks shared by the requests about one plan (_OPEN says where their fields
        are and what they need) -> its MissionStore, or None once refused."""
        how = _OPEN[link.rx.msgid - _MSG_REQUEST_PARTIAL_LIST]
        at = how & 7
        if not self.ep.for_us(p[at], p[at + 1]):
            return None
        how = self._admit(link, p[at + 2] if self.has_type else 0, how)  # -> the plan type
        return self.stores[how] if how >= 0 else None

    def _admit(self, link, mt, how):
        """A request of plan type mt may start -> mt, or -1 once refused."""
        result = _DENIED
        if how & _CHANGE and not self.ep.allows(link):
            pass
        elif not self._may_start(link, how):
            pass  # one transfer at a time: the one under way goes on
        elif (mt == _TYPE_MISSION or (mt == _TYPE_ALL and how & _EVERY)
              or (mt < 3 and link.version == 2 and self.has_type and self.stores[mt] is not None)):
            self._end_for(link, how)
            return mt
        else:
            result = _UNSUPPORTED  # fence and rally need MAVLink 2
        self._reply(link, result, mt)
        return -1

    def _may_start(self, link, how):
        """May link's request (how: its _OPEN bits) start beside or over the transfer under way?"""
        state = self.state
        if state == _IDLE or self._is_peer(link):
            return True
        if how & _CHANGE:  # the plan changes: reads give way, and an upload that is not moving
            return state != _UPLOAD or not self.t_moved
        # A download goes beside another's download or partial read; a partial read
        # (which the vehicle pushes) takes the slot from a download, not from another push.
        return state == _DOWNLOAD or (state == _PUSH and link.rx.msgid == _MSG_REQUEST_LIST)

    def _end_for(self, link, how):
        """What becomes of the transfer under way, now that link's request starts: its own
        peer starts over (its progress clock runs on); another's is cancelled where the
        plan changes, and left to go on where a download starts beside it."""
        self.t_share = False
        if self.state == _IDLE:
            self.t_fresh = True
        elif self._is_peer(link):
            self.t_fresh = False
        elif how & _CHANGE:
            self._cancel()
            self.t_fresh = True
        elif link.rx.msgid == _MSG_REQUEST_LIST:
            self.t_share = True  # served beside it: the slot stays with the other
            return
        else:
            self.t_fresh = True  # a partial read takes the slot; the download goes on unlocked
        self.state = _IDLE

    def _start(self, link, state, store):
        """A transfer with link's sender begins (the caller sets t_seq, t_end)."""
        rx = link.rx
        self.state = state
        self.t_link = link
        self.t_peer = rx.sysid << 8 | rx.compid
        self.t_store = store
        self.t_int = self.has_int and rx.version == 2
        self.t_sent = self.ep.now
        if self.t_fresh:  # (a restart keeps how far the transfer had come)
            self.t_progress = self.ep.now
            self.t_seq = 0
            self.upload.reach = 0
        self.t_fresh = True
        self.t_moved = False
        self.done_seq = -1

    def _cancel(self):
        """The transfer under way ends unfinished (an upload's staged items are dropped);
        its ground station is told."""
        self.state = _IDLE
        link = self.t_link
        self._ack(link, self.t_peer, _OPERATION_CANCELLED if link.version == 2 else _ERROR,
                  self.t_store.mission_type)

    # --- upload (mission_upload.py) -------------------------------------------------
    def _on_count(self, link, p):
        count = u16(p, 0)
        if self._late_count(link, p, count):
            return  # a late copy of the MISSION_COUNT that started this upload
        store = self._store(link, p)
        if store is None:
            return
        if count > store.capacity:
            self._reply(link, _NO_SPACE, store.mission_type)
        elif count == 0:
            self._reply(link, self._clear(store), store.mission_type)
        else:
            self.t_count = count
            self.t_end = count - 1
            self.upload.start(link, store, 0, 0)

    def _late_count(self, link, p, count):
        # During its upload, a count the uploader sent before the one that started it
        # (held back by the link: see mission_upload.py), or a copy of that one once
        # items are in: not a new upload.
        up = self.upload
        if self.state != _UPLOAD or not self._is_peer(link):
            return False
        return sent_before(link.rx, up.origin) or (
            up.first == 0 and count == self.t_count and (up.base > 0 or up.held != 0)
            and (p[4] if self.has_type else 0) == self.t_store.mission_type)

    def _on_item(self, link, p):
        # MISSION_ITEM_INT and the seed's MISSION_ITEM share their layout but for x and y.
        if not self.ep.for_us(p[32], p[33]):
            return
        if p[35] >= 2 and self.on_guided is not None:
            self._guided(link, p)
        elif self.state != _UPLOAD or not self._is_peer(link):
            self._on_rare(link, p)  # a repeat of the last item whose ACK was lost?
        elif (p[37] if self.has_type else 0) == self.t_store.mission_type:
            self.upload.item(link, p, u16(p, 28))

    def _guided(self, link, p):
        # current 2 / 3: not a plan's item but ArduPilot's "guided" go-to / change altitude
        # (MAVProxy's `guided`): the application's, answered with its result. (Apart from
        # _on_item: its frame state stays within what MicroPython keeps off the heap.)
        result = self.on_guided(link, p, link.rx.msgid == _MSG_ITEM_INT)
        self._reply(link, result, 0)

    def _commit(self, store, count):
        if not store.seal(count):
            return self._unsaved()
        if store.mission_type == _TYPE_MISSION and store.staged_jumps > self.jump_slots:
            return _NO_SPACE  # more DO_JUMPs than the runner keeps counters for
        return _ACCEPTED if store.commit() else self._unsaved()

    def _unsaved(self):
        self.ep.statustext(_SEVERITY_ERROR, b"Mission not saved: storage refused it")
        return _ERROR

    def _clear(self, store):
        if not store.begin(0):
            return self._unsaved()
        result = self._commit(store, 0)
        if result == _ACCEPTED:
            self._plan_changed(store, 0)
        return result

    def _storage_failed(self, link, store):
        """A new plan cannot be staged (storage full, read-only or failing): MISSION_ACK
        error to its sender; the plan in force stands."""
        self._reply(link, self._unsaved(), store.mission_type)

    def _plan_changed(self, store, current):
        if store.mission_type == _TYPE_MISSION and self.runner is not None:
            self.runner.plan_changed(current)
        self.current_changed()

    # --- download -----------------------------------------------------------------
    def _on_request_list(self, link, p):
        store = self._store(link, p)
        if store is None:
            return
        if store.count and not self.t_share:
            self._start(link, _DOWNLOAD, store)
            self.t_end = store.count - 1
        off = link.begin()
        buf = link.txbuf
        buf[off] = store.count & 0xFF
        buf[off + 1] = store.count >> 8
        buf[off + 2] = link.rx.sysid
        buf[off + 3] = link.rx.compid
        buf[off + 4] = store.mission_type
        store.put_plan_id(buf, off + 5)  # opaque_id, where the dialect has it
        link.send(_MSG_COUNT)

    def _on_request(self, link, p):
        # MISSION_REQUEST_INT is answered with MISSION_ITEM_INT, the seed's MISSION_REQUEST
        # with MISSION_ITEM; answered whenever no other ground station has a transfer open.
        if not self.ep.for_us(p[2], p[3]):
            return
        mt = p[4] if self.has_type else 0
        if self.state == _UPLOAD:  # reads wait for an upload; its own uploader knows better
            if not self._is_peer(link):
                self._reply(link, _DENIED, mt)
            return
        store = self.stores[mt] if mt < 3 and (mt == 0 or link.version == 2) else None
        seq = u16(p, 0)
        if store is None:
            self._reply(link, _UNSUPPORTED, mt)
        else:
            self._serve(link, store, seq)

    def _serve(self, link, store, seq):
        if seq >= store.count:
            if self._mine(link):
                self.state = _IDLE
            self._reply(link, _INVALID_SEQUENCE, store.mission_type)
            return
        self._send_item(link, store, seq, link.rx.msgid == _MSG_REQUEST_INT)
        if self._mine(link):
            self._served(seq)

    def _mine(self, link):
        """The frame in hand comes from the ground station whose download holds the slot."""
        return self.state == _DOWNLOAD and self._is_peer(link)

    def _served(self, seq):
        if seq >= self.t_seq:
            self.t_seq = seq + 1  # a new item served: progress (a restart's repeats are not)
            self.t_progress = self.ep.now
        if seq == self.t_end:
            self.state = _IDLE  # the last item: done, whether or not an ACK follows

    def _send_item(self, link, store, seq, as_int):
        if not store.read(seq, self._rec):
            return
        off = self._item_into(link, seq, store.mission_type)
        if as_int:
            link.send(_MSG_ITEM_INT)
        else:  # the seed's MISSION_ITEM: x, y as float degrees (metres if local)
            unfix(link.txbuf, off + 16, self._rec[30] in LOCAL_FRAMES)
            unfix(link.txbuf, off + 20, self._rec[30] in LOCAL_FRAMES)
            link.send(_MSG_ITEM)

    def _item_into(self, link, seq, mt):
        """MISSION_ITEM_INT's payload in link.txbuf from record seq (in self._rec) -> its offset."""
        off = link.begin()
        buf = link.txbuf
        copy(buf, self._rec, off, 28)
        buf[off + 28] = seq & 0xFF
        buf[off + 29] = seq >> 8
        buf[off + 30] = self._rec[28]
        buf[off + 31] = self._rec[29]
        buf[off + 32] = link.rx.sysid
        buf[off + 33] = link.rx.compid
        buf[off + 34] = self._rec[30]
        buf[off + 35] = 1 if mt == _TYPE_MISSION and self.runner is not None and seq == self.runner.current else 0
        buf[off + 36] = self._rec[31]
        buf[off + 37] = mt
        return off

    def _on_ack(self, link, p):
        # The peer ends its download, or cancels its upload (nothing is stored then).
        if (self.ep.for_us(p[0], p[1]) and self.state != _IDLE and self._is_peer(link)
                and (p[3] if self.has_type else 0) == self.t_store.mission_type):
            self.state = _IDLE

    # --- what a ground station seldom sends ------------------------------------------
    def _on_rare(self, link, p):
        """Partial lists, MISSION_CLEAR_ALL, MISSION_SET_CURRENT, items outside an upload:
        mission_rare.py, loaded on first use (at start-up where the heap gets locked)."""
        if self.rare is None:
            from . import rare as mission_rare

            self.rare = mission_rare
        self.rare.on(self, link, p)

    # --- current item -------------------------------------------------------------
    def send_current(self, link):
        off = link.begin()
        buf = link.txbuf
        self._current_into(buf, off)
        # mission_id, fence_id, rally_points_id, where the dialect has them
        self._put_id(buf, off + 6, 0)
        self._put_id(buf, off + 10, 1)
        self._put_id(buf, off + 14, 2)
        return link.send(_MSG_CURRENT)

    def _current_into(self, buf, off):
        runner = self.runner
        count = self.stores[0].count
        seq = 0
        if runner is not None:
            seq = runner.current
            buf[off + 4] = runner.state
            buf[off + 5] = runner.mode
        else:
            buf[off + 4] = _STATE_NOT_STARTED if count else _STATE_NO_MISSION
            buf[off + 5] = 0  # unknown: nothing here flies missions
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        count = count or 0xFFFF  # UINT16_MAX: no mission
        buf[off + 2] = count & 0xFF
        buf[off + 3] = count >> 8

    def _put_id(self, buf, o, mt):
        """The plan id of type mt at buf[o] (u32), 0 without such a plan."""
        store = self.stores[mt] if mt < 3 else None
        if store is None:
            buf[o] = buf[o + 1] = buf[o + 2] = buf[o + 3] = 0
        else:
            store.put_plan_id(buf, o)

    def send_reached(self, seq):
        links = self.ep.links
        for i in range(len(links)):
            off = links[i].begin()
            links[i].txbuf[off] = seq & 0xFF
            links[i].txbuf[off + 1] = seq >> 8
            links[i].send(_MSG_ITEM_REACHED)

    def _reply(self, link, result, mt):
        """MISSION_ACK to the sender of the frame in hand."""
        self._ack(link, link.rx.sysid << 8 | link.rx.compid, result, mt)

    def _ack(self, link, peer, result, mt):
        off = link.begin()
        link.txbuf[off] = peer >> 8
        link.txbuf[off + 1] = peer & 0xFF
        link.txbuf[off + 2] = result
        link.txbuf[off + 3] = mt
        # opaque_id (where the dialect has it): the new plan's id after an upload.
        self._put_id(link.txbuf, off + 4, 3 if result else mt)
        link.send(_MSG_ACK)


def create(ep):
    gc.collect()  # the stores and tables below are long-lived: start them on a tidy heap
    board = getattr(ep, "board", None)
    missions = ep.add(Missions(
        ep.storage,
        capacities=(ep.setting("MISSION_CAPACITY", 500), ep.setting("FENCE_CAPACITY", 100),
                    ep.setting("RALLY_CAPACITY", 20)),
        frames=getattr(board, "MISSION_FRAMES", (0, 2, 3, 5, 6)),
        retry_ms=ep.setting("MISSION_RETRY_MS", 250),
        retries=ep.setting("MISSION_RETRIES", 5),
        timeout_ms=ep.setting("MISSION_TIMEOUT_MS", 5000),
        jump_slots=ep.setting("MISSION_JUMP_SLOTS", 16),
        commands=getattr(board, "MISSION_COMMANDS", ()),
        window=ep.setting("MISSION_WINDOW", 8),
        rto_min=ep.setting("MISSION_RTO_MIN_MS", 20),
        rto_max=ep.setting("MISSION_RTO_MAX_MS", 1000),
    ))
    if ep.setting("MISSION_RUNNER", True):
        from .runner import MissionRunner

        MissionRunner(missions)
    if ep.setting("HEAP_LOCK", False):  # no loading on first use once the heap is locked
        from . import rare as mission_rare

        missions.rare = mission_rare
    return missions
