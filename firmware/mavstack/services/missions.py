"""Mission protocol, vehicle side: mission, fence and rally plans, uploaded, downloaded,
cleared, partially read and written, with the current item and its progress.

Upload: MISSION_COUNT -> MISSION_REQUEST_INT per item (MISSION_REQUEST to a ground
station that speaks MAVLink 1 or answers with the seed's MISSION_ITEM) -> MISSION_ACK.
Items go straight into the store's staging slot (mission_store.py) and replace the
plan only once the last one is accepted; any failure leaves the stored plan as it was.
Download: MISSION_REQUEST_LIST -> MISSION_COUNT, then each MISSION_REQUEST_INT or
MISSION_REQUEST answered from flash; the ground station's final ACK is welcome, not
needed. The seed's MISSION_REQUEST_PARTIAL_LIST pushes the range (paced to the link);
MISSION_WRITE_PARTIAL_LIST updates a range of the plan in force.
One transfer at a time: another ground station is told MAV_MISSION_DENIED meanwhile.
Partial lists, MISSION_CLEAR_ALL, MISSION_SET_CURRENT and items outside an upload are
handled in mission_rare.py, loaded when the first of them comes (at start-up on a board
that locks its heap): a ground station seldom sends them, and a small board's heap
holds that code only once it is used.
The vehicle re-requests a missing item every retry_ms, and gives up after `retries`
re-requests or timeout_ms of silence (OPERATION_CANCELLED, or ERROR to MAVLink 1).
Fence and rally need MAVLink 2 (mission_type is an extension field).

Frames are written byte by byte at the payload offsets, so the same code serves the
seed dialect (no MISSION_ITEM_INT, no extension fields) and dialects whose MISSION_COUNT,
MISSION_ACK and MISSION_CURRENT carry plan ids (opaque_id): the encoder cuts each
payload to the length the dialect gives it. Nothing here allocates once a transfer
has started, on a 32-bit board too, where an int of 2^30 or more is a heap object:
coordinates (1e7 degrees reach 1.8e9) stay in their bytes, are range-checked by 16-bit
halves and converted to and from the seed's float degrees by small-int arithmetic, and
plan ids are written as bytes. Handlers are split into short functions: MicroPython
puts a frame of more than 11 words (locals + stack) on the heap.

    missions = ep.services["missions"]
    missions.stores[0|1|2]      the MissionStore of each plan type (None for a capacity of
                                0: a board without geofence or rally points)
    missions.runner             mission_runner.MissionRunner, what the application flies
                                (None on a board with MISSION_RUNNER = False: plans are
                                kept and served, MISSION_START is UNSUPPORTED)
    missions.allow(command, need=0)   a MAV_CMD the application flies (need: _P*/_POS bits)
"""
import gc

from ..compat import const, ticks_diff, ticks_add
from ..fields import u16, i32_cmp, f32_is_nan, f32_to_small
from ..kernels import copy
from .mission_store import MissionStore, RECORD_SIZE

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
_UNSUPPORTED_FRAME = const(2)
_UNSUPPORTED = const(3)
_NO_SPACE = const(4)
_INVALID_PARAM1 = const(6)
_INVALID_PARAM5_X = const(10)
_INVALID_PARAM6_Y = const(11)
_INVALID_PARAM7 = const(12)
_INVALID_SEQUENCE = const(13)
_DENIED = const(14)
_OPERATION_CANCELLED = const(15)

_TYPE_MISSION = const(0)
_TYPE_ALL = const(255)
_CMD_DO_JUMP = const(177)
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
_FRAME_MISSION = const(2)
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

# Position bounds in 1e7 degrees, as (signed high half, low half): +-90e7, +-180e7.
_LAT_MAX_HI = const(13732)  # 900000000 = 13732 * 65536 + 59648
_LAT_MAX_LO = const(59648)
_LAT_MIN_HI = const(-13733)  # -900000000 = -13733 * 65536 + 5888
_LAT_MIN_LO = const(5888)
_LON_MAX_HI = const(27465)  # 1800000000 = 27465 * 65536 + 53760
_LON_MAX_LO = const(53760)
_LON_MIN_HI = const(-27466)  # -1800000000 = -27466 * 65536 + 11776
_LON_MIN_LO = const(11776)

# What an item's command needs, per MAV_MISSION_TYPE: 3 bytes a command, its id (little
# endian) and what it needs: bits 0-3 param1-4 must be numbers, _P7 z must be a
# number, _POS x/y are a position (range-checked in global frames, refused in
# MAV_FRAME_MISSION). Bytes, not tuples: a small board keeps them in one object.
_P1 = const(1)
_P2 = const(2)
_P7 = const(64)
_POS = const(128)
_MISSION_RULES = (  # the seed's NAV, CONDITION and DO commands
    b"\x10\x00\xc0"  # 16 NAV_WAYPOINT: _POS | _P7
    b"\x11\x00\xc0"  # 17 NAV_LOITER_UNLIM: _POS | _P7
    b"\x12\x00\xc1"  # 18 NAV_LOITER_TURNS: _POS | _P7 | _P1
    b"\x13\x00\xc1"  # 19 NAV_LOITER_TIME: _POS | _P7 | _P1
    b"\x14\x00\x00"  # 20 NAV_RETURN_TO_LAUNCH
    b"\x15\x00\x80"  # 21 NAV_LAND: _POS (z NaN: land at ground level)
    b"\x16\x00\xc0"  # 22 NAV_TAKEOFF: _POS | _P7
    b"\x50\x00\x00"  # 80 NAV_ROI
    b"\x51\x00\x00"  # 81 NAV_PATHPLANNING
    b"\x70\x00\x01"  # 112 CONDITION_DELAY: _P1
    b"\x71\x00\x41"  # 113 CONDITION_CHANGE_ALT: _P1 | _P7
    b"\x72\x00\x01"  # 114 CONDITION_DISTANCE: _P1
    b"\x73\x00\x01"  # 115 CONDITION_YAW: _P1
    b"\xb0\x00\x01"  # 176 DO_SET_MODE: _P1
    b"\xb1\x00\x03"  # 177 DO_JUMP: _P1 | _P2
    b"\xb2\x00\x02"  # 178 DO_CHANGE_SPEED: _P2
    b"\xb3\x00\x01"  # 179 DO_SET_HOME: _P1
    b"\xb4\x00\x03"  # 180 DO_SET_PARAMETER: _P1 | _P2
    b"\xb5\x00\x03"  # 181 DO_SET_RELAY: _P1 | _P2
    b"\xb6\x00\x03"  # 182 DO_REPEAT_RELAY: _P1 | _P2
    b"\xb7\x00\x03"  # 183 DO_SET_SERVO: _P1 | _P2
    b"\xb8\x00\x03"  # 184 DO_REPEAT_SERVO: _P1 | _P2
    b"\xc8\x00\x00"  # 200 DO_CONTROL_VIDEO
)
_FENCE_RULES = (
    b"\x88\x13\x80"  # 5000 NAV_FENCE_RETURN_POINT: _POS
    b"\x89\x13\x81"  # 5001 NAV_FENCE_POLYGON_VERTEX_INCLUSION: _POS | _P1 (vertex count)
    b"\x8a\x13\x81"  # 5002 NAV_FENCE_POLYGON_VERTEX_EXCLUSION: _POS | _P1
    b"\x8b\x13\x81"  # 5003 NAV_FENCE_CIRCLE_INCLUSION: _POS | _P1 (radius)
    b"\x8c\x13\x81"  # 5004 NAV_FENCE_CIRCLE_EXCLUSION: _POS | _P1
)
_RALLY_RULES = b"\xec\x13\xc0"  # 5100 NAV_RALLY_POINT: _POS | _P7
_RULES = (_MISSION_RULES, _FENCE_RULES, _RALLY_RULES)
_LOCAL_FRAMES = b"\x01\x04\x07\x08\x09\x0c\x14\x15"  # x, y in metres (* 1e4 in MISSION_ITEM_INT)
_NAMES = ("mission", "fence", "rally")  # also their files' names in storage


class Missions:
    NAME = "missions"
    CLOCK = False  # tells no time: a board with missions alone makes no ep.clock
    # Set on the instance where there is one (at start-up: no dict growth later).
    extra = None  # {command: need} the application added to the mission rules (allow)
    runner = None  # mission_runner.MissionRunner
    rare = None  # mission_rare.py, once loaded (see _on_rare)

    def __init__(self, storage, capacities=(500, 100, 20), frames=(0, 2, 3, 5, 6), retry_ms=250,
                 retries=5, timeout_ms=5000, jump_slots=16, commands=()):
        # (Few attributes: on a small heap a bigger instance dict may not find room.)
        self.stores = [None, None, None]
        for t in range(3):
            if capacities[t] or t == 0:
                self.stores[t] = MissionStore(storage, _NAMES[t], t, capacities[t])
        self.frames = frames
        self.retry_ms = retry_ms
        self.retries = retries
        self.timeout_ms = timeout_ms
        self.jump_slots = jump_slots
        for command in commands:
            self.allow(command)
        self._rec = bytearray(RECORD_SIZE)
        # The transfer under way (one at a time) and its peer.
        self.state = _IDLE
        self.t_link = None
        self.t_peer = 0  # its sysid << 8 | compid
        self.t_store = None
        self.t_count = 0  # items in the plan once this upload is done
        self.t_seq = 0  # upload: next item expected; partial download: next to push
        self.t_end = 0  # last item of this transfer
        self.t_int = True  # upload: ask with MISSION_REQUEST_INT (else the seed's MISSION_REQUEST)
        self.t_current = -1  # upload: the item sent with current=1, -2: keep the current one
        self.t_sent = 0  # ticks of the last request / push
        self.t_heard = 0  # ticks of the last frame from the peer
        self.t_tries = 0
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
        if state == _UPLOAD and ticks_diff(now, self.t_sent) >= self.retry_ms:
            self._retry(now)
        elif state == _PUSH:
            self.rare.push(self, now)
        elif state == _DOWNLOAD and ticks_diff(now, self.t_heard) >= self.timeout_ms:
            self.state = _IDLE  # the ground station went away; nothing to undo
        # On change; and once a second unless the streams service schedules it (it is
        # in the default streams there, and a ground station may change its rate).
        if self._current_changed or (
            ticks_diff(now, self._current_due) >= 0 and self.ep.services.get("streams") is None
        ):
            for link in self.ep.links:
                self.send_current(link)
            self._current_changed = False
            self._current_due = ticks_add(now, _CURRENT_PERIOD_MS)

    def _retry(self, now):
        if self.t_tries >= self.retries or ticks_diff(now, self.t_heard) >= self.timeout_ms:
            self.state = _IDLE
            link = self.t_link
            self._ack(link, self.t_peer, _OPERATION_CANCELLED if link.version == 2 else _ERROR,
                      self.t_store.mission_type)
        else:
            self.t_tries += 1
            self._request(self.t_seq)

    def current_changed(self):
        """Send MISSION_CURRENT on the next tick (the runner calls this)."""
        self._current_changed = True

    # --- starting a transfer ------------------------------------------------------
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
        elif self.state != _IDLE and not self._is_peer(link):
            pass  # one transfer at a time; the one under way goes on
        elif (mt == _TYPE_MISSION or (mt == _TYPE_ALL and how & _EVERY)
              or (mt < 3 and link.version == 2 and self.has_type and self.stores[mt] is not None)):
            self.state = _IDLE  # the peer starts over: whatever it had under way is dropped
            return mt
        else:
            result = _UNSUPPORTED  # fence and rally need MAVLink 2
        self._reply(link, result, mt)
        return -1

    def _start(self, link, state, store):
        """A transfer with link's sender begins (the caller sets t_seq, t_end)."""
        rx = link.rx
        self.state = state
        self.t_link = link
        self.t_peer = rx.sysid << 8 | rx.compid
        self.t_store = store
        self.t_int = self.has_int and rx.version == 2
        self.t_tries = 0
        self.t_heard = self.t_sent = self.ep.now
        self.done_seq = -1

    # --- upload -------------------------------------------------------------------
    def _on_count(self, link, p):
        count = u16(p, 0)
        if (self.state == _UPLOAD and self._is_peer(link) and self.t_seq > 0 and count == self.t_count
                and self.t_end == count - 1 and (p[4] if self.has_type else 0) == self.t_store.mission_type):
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
            self.t_seq = 0
            self.t_end = count - 1
            self._upload(link, store, 0)

    def _upload(self, link, store, keep):
        """Ask for items t_seq .. t_end of a plan of t_count (keep: items copied first)."""
        self._start(link, _UPLOAD, store)
        self.t_current = -1 if self.t_seq == 0 and keep == 0 else -2
        store.begin(keep)
        self._request(self.t_seq)

    def _request(self, seq):
        link = self.t_link
        off = link.begin()
        buf = link.txbuf
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        buf[off + 2] = self.t_peer >> 8
        buf[off + 3] = self.t_peer & 0xFF
        buf[off + 4] = self.t_store.mission_type
        link.send(_MSG_REQUEST_INT if self.t_int else _MSG_REQUEST)
        self.t_sent = self.ep.now

    def _on_item(self, link, p):
        # MISSION_ITEM_INT and the seed's MISSION_ITEM share their layout but for x and y.
        if not self.ep.for_us(p[32], p[33]):
            return
        if self.state != _UPLOAD or not self._is_peer(link):
            self._on_rare(link, p)  # a repeat of the last item whose ACK was lost?
            return
        if (p[37] if self.has_type else 0) != self.t_store.mission_type:
            return
        self.t_heard = self.ep.now
        seq = u16(p, 28)
        if seq == self.t_seq:
            self._take(link, p, seq)
        elif seq + 1 != self.t_seq:
            # Out of sequence: ignored. A copy of the previous item (a duplicate, or one
            # that crossed our re-request) waits for the retry timer, so that duplicates
            # cannot breed more duplicates; anything else has the expected one re-requested.
            self._request(self.t_seq)

    def _take(self, link, p, seq):
        """The item expected: check it, store it, ask for the next or finish."""
        is_int = link.rx.msgid == _MSG_ITEM_INT
        if not is_int:
            self.t_int = False  # it speaks the seed's messages: ask in its terms
        result = self._check(p, is_int, seq)
        if result == _ACCEPTED and not self.t_store.put(seq, self._rec):
            result = _ERROR
        if result != _ACCEPTED:
            self.state = _IDLE
            self._reply(link, result, self.t_store.mission_type)
            return
        if p[35] == 1 and self.t_current != -2:
            self.t_current = seq
        if seq < self.t_end:
            self.t_seq = seq + 1
            self.t_tries = 0
            self._request(seq + 1)
        else:
            self._finish(link, seq)

    def _finish(self, link, seq):
        self.state = _IDLE
        store = self.t_store
        result = self._commit(store, self.t_count)
        if result == _ACCEPTED:
            self.done_link = link
            self.done_key = self.t_peer << 8 | store.mission_type
            self.done_seq = seq
            self._plan_changed(store, 0 if self.t_current == -1 else self.t_current)  # -2: keep
        self._reply(link, result, store.mission_type)

    def _commit(self, store, count):
        if not store.seal(count):
            return _ERROR
        if store.mission_type == _TYPE_MISSION and store.staged_jumps > self.jump_slots:
            return _NO_SPACE  # more DO_JUMPs than the runner keeps counters for
        return _ACCEPTED if store.commit() else _ERROR

    def _clear(self, store):
        store.begin(0)
        result = self._commit(store, 0)
        if result == _ACCEPTED:
            self._plan_changed(store, 0)
        return result

    def _plan_changed(self, store, current):
        if store.mission_type == _TYPE_MISSION and self.runner is not None:
            self.runner.plan_changed(current)
        self.current_changed()

    def _check(self, p, is_int, seq):
        """Validate an item and build its record in self._rec -> MAV_MISSION_RESULT."""
        copy(self._rec, p, 0, 28)  # params, x, y, z as they came
        self._rec[28] = p[30]  # command
        self._rec[29] = p[31]
        self._rec[30] = p[34]  # frame
        self._rec[31] = p[36]  # autocontinue
        frame = p[34]
        if frame not in self.frames:
            return _UNSUPPORTED_FRAME
        need = self._need(u16(p, 30))
        if need < 0:
            return _UNSUPPORTED
        if need & _POS and frame == _FRAME_MISSION:
            return _UNSUPPORTED_FRAME
        return (self._xy(frame in _LOCAL_FRAMES, need, is_int) or _numbers(p, need)
                or (self._jump(p, seq) if u16(p, 30) == _CMD_DO_JUMP else _ACCEPTED))

    def _need(self, command):
        """What the command needs (_P*, _POS bits), -1 if this plan type does not take it."""
        mt = self.t_store.mission_type
        rules = _RULES[mt]
        for i in range(0, len(rules), 3):
            if rules[i] | rules[i + 1] << 8 == command:
                return rules[i + 2]
        if mt == _TYPE_MISSION and self.extra is not None:
            return self.extra.get(command, -1)
        return -1

    def _xy(self, local, need, is_int):
        """x, y of the record: the seed's float degrees made integers, then range-checked."""
        rec = self._rec
        pos = need & _POS
        if not is_int:
            # NaN or beyond int32: refused where a position is needed, else stored as 0.
            if not _fix(rec, 16, local) and pos:
                return _INVALID_PARAM5_X
            if not _fix(rec, 20, local) and pos:
                return _INVALID_PARAM6_Y
        if pos and not local:
            if i32_cmp(rec, 16, _LAT_MAX_HI, _LAT_MAX_LO) > 0 or i32_cmp(rec, 16, _LAT_MIN_HI, _LAT_MIN_LO) < 0:
                return _INVALID_PARAM5_X
            if i32_cmp(rec, 20, _LON_MAX_HI, _LON_MAX_LO) > 0 or i32_cmp(rec, 20, _LON_MIN_HI, _LON_MIN_LO) < 0:
                return _INVALID_PARAM6_Y
        return _ACCEPTED

    def _jump(self, p, seq):
        # f32_to_small: a target or repeat count beyond 2^30 is as wrong as any other.
        target = f32_to_small(p, 0)
        if target < 0 or target >= self.t_count or target == seq:
            return _INVALID_PARAM1
        if f32_to_small(p, 4) < -1:
            return _INVALID_PARAM1 + 1
        return _ACCEPTED

    # --- download -----------------------------------------------------------------
    def _on_request_list(self, link, p):
        store = self._store(link, p)
        if store is None:
            return
        if store.count:
            self._start(link, _DOWNLOAD, store)
            self.t_seq = 0
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
        if self.state == _UPLOAD or (self.state != _IDLE and not self._is_peer(link)):
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
            self.state = _IDLE
            self._reply(link, _INVALID_SEQUENCE, store.mission_type)
            return
        self.t_heard = self.ep.now
        self._send_item(link, store, seq, link.rx.msgid == _MSG_REQUEST_INT)
        if self.state == _DOWNLOAD and seq == self.t_end:
            self.state = _IDLE  # the last item: done, whether or not an ACK follows

    def _send_item(self, link, store, seq, as_int):
        if not store.read(seq, self._rec):
            return
        off = self._item_into(link, seq, store.mission_type)
        if as_int:
            link.send(_MSG_ITEM_INT)
        else:  # the seed's MISSION_ITEM: x, y as float degrees (metres if local)
            _unfix(link.txbuf, off + 16, self._rec[30] in _LOCAL_FRAMES)
            _unfix(link.txbuf, off + 20, self._rec[30] in _LOCAL_FRAMES)
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
            from . import mission_rare

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


def _numbers(p, need):
    """NaN where the command needs a number -> INVALID_PARAM1..4, 7; else ACCEPTED."""
    for i in range(4):
        if need & (1 << i) and f32_is_nan(p, i * 4):
            return _INVALID_PARAM1 + i
    if need & _P7 and f32_is_nan(p, 24):
        return _INVALID_PARAM7
    return _ACCEPTED


# --- MISSION_ITEM's float32 degrees <-> MISSION_ITEM_INT's int32 ---------------------
# Exact, and with small ints only: a float32 is m * 2**(e-150) (m < 2**24), so
# f * 10**k = m * 5**k / 2**(150-e-k), where m * 5**k < 2**41 is held as two ints.
# The other way is long division, 4 bits and then 1 bit at a time.
_acc = [0, 0]  # the scratch of the conversions: a wide number as two small ints


def _fix(rec, o, local):
    """In place: the float32 at rec[o] (degrees; metres where local) -> the int32 of
    MISSION_ITEM_INT (* 1e7; * 1e4 where local), nearest, halves away from zero.
    False, and 0 written, for NaN, infinities and values beyond int32."""
    e = (rec[o + 3] & 0x7F) << 1 | rec[o + 2] >> 7
    # |f| >= 2**(e-127): beyond 2**31 / 10**k it cannot fit an int32 (NaN, inf: e 255).
    if e > (144 if local else 134):
        return _put_i32(rec, o, False)
    # m * 5**k = H * 2**24 + L into _acc, by 12-bit pieces of m (5**7 < 2**17).
    m = (rec[o + 2] & 0x7F | (0x80 if e else 0)) << 16 | rec[o + 1] << 8 | rec[o]
    a = (m >> 12) * (625 if local else 78125)  # < 2**12 * 5**7 < 2**29
    m = (m & 0xFFF) * (625 if local else 78125) + ((a & 0xFFF) << 12)  # < 2**30
    _acc[0] = (a >> 12) + (m >> 24)
    _acc[1] = m & 0xFFFFFF
    _shift((149 if e == 0 else 150 - e) - (4 if local else 7))  # e 0: subnormal
    return _put_i32(rec, o, _acc[0] <= 0x7FFF)  # beyond int32: 0


def _shift(s):
    """_acc = (H, L) -> v = round((H * 2**24 + L) / 2**s), halves up, as (v >> 16, v & 0xFFFF)."""
    if s > 41:  # H * 2**24 + L < 2**41: below one half
        _acc[0] = _acc[1] = 0
        return
    h = _acc[0]
    low = _acc[1]
    if s <= 24:
        low += 1 << (s - 1)
    else:
        h += 1 << (s - 25)
    h += low >> 24
    low &= 0xFFFFFF
    _acc[0] = _bits16(h, low, s + 16)
    _acc[1] = _bits16(h, low, s)


def _bits16(h, low, t):
    """Bits t .. t+15 of h * 2**24 + low (h < 2**18, low < 2**24)."""
    if t >= 24:
        return (h >> (t - 24)) & 0xFFFF
    v = low >> t
    if t > 8:  # h's lowest t - 8 bits land below bit 16
        v |= (h & ((1 << (t - 8)) - 1)) << (24 - t)
    return v & 0xFFFF


def _put_i32(buf, o, ok):
    """buf[o:o+4] <- the magnitude in _acc (high half, low half) as an int32, negated if
    buf[o+3] has its sign bit set (the float's, or the int's); 0 if not ok -> ok."""
    hi = _acc[0] if ok else 0
    lo = _acc[1] if ok else 0
    if ok and buf[o + 3] & 0x80:  # two's complement by halves: the carry of -lo goes into ~hi
        lo = -lo & 0xFFFF
        hi = (~hi + (lo == 0)) & 0xFFFF
    buf[o] = lo & 0xFF
    buf[o + 1] = lo >> 8
    buf[o + 2] = hi & 0xFF
    buf[o + 3] = hi >> 8
    return ok


def _unfix(buf, o, local):
    """In place: the int32 at buf[o] -> the float32 nearest to it / 1e7 (/ 1e4 where
    local), ties to even (its bits)."""
    neg = buf[o + 3] & 0x80
    if neg:  # the magnitude first, in place, by halves (2**31 too: 0x8000, 0)
        _acc[0] = buf[o + 2] | buf[o + 3] << 8
        _acc[1] = buf[o] | buf[o + 1] << 8
        _put_i32(buf, o, True)
    if not (buf[o] or buf[o + 1] or buf[o + 2] or buf[o + 3]):
        return  # 0: the bits of 0.0 are already there
    d = 10000 if local else 10000000
    _acc[0] = _acc[1] = 0
    _div16(buf[o + 2] | buf[o + 3] << 8, d)
    _div16(buf[o] | buf[o + 1] << 8, d)
    d = 150 - _frac(d)  # the biased exponent; the 24-bit significand is in _acc[0]
    q = _acc[0]
    buf[o] = q & 0xFF
    buf[o + 1] = (q >> 8) & 0xFF
    buf[o + 2] = (d & 1) << 7 | (q >> 16) & 0x7F
    buf[o + 3] = neg | d >> 1


def _div16(x, d):
    """Long division: (quotient, remainder) by d in _acc, continued by the 16 bits of x,
    4 at a time (the remainder is below d, so remainder * 16 stays small)."""
    n = 12
    while n >= 0:
        r = _acc[1] << 4 | (x >> n) & 0xF
        _acc[0] = _acc[0] << 4 | r // d
        _acc[1] = r % d
        n -= 4


def _frac(d):
    """Binary digits of remainder / d appended to the quotient until it has 24
    significant bits, then rounded to nearest, ties to even -> how many were appended.
    (The quotient is below 2**31 / 10**4 < 2**23 to begin with.)"""
    q = _acc[0]
    r = _acc[1]
    n = 0
    while q < 0x800000:
        q <<= 1
        r <<= 1
        if r >= d:
            r -= d
            q |= 1
        n += 1
    r <<= 1
    if r > d or (r == d and q & 1):
        q += 1
        if q == 0x1000000:
            q >>= 1
            n -= 1
    _acc[0] = q
    return n


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
    ))
    if ep.setting("MISSION_RUNNER", True):
        from .mission_runner import MissionRunner

        MissionRunner(missions)
    if ep.setting("HEAP_LOCK", False):  # no loading on first use once the heap is locked
        from . import mission_rare

        missions.rare = mission_rare
    return missions
