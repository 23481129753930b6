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
The vehicle re-requests a missing item every retry_ms, and gives up after `retries`
re-requests or timeout_ms of silence (OPERATION_CANCELLED, or ERROR to MAVLink 1).
Fence and rally need MAVLink 2 (mission_type is an extension field).

Frames are written byte by byte at the payload offsets, so the same code serves the
seed dialect (no MISSION_ITEM_INT, no extension fields) and dialects whose MISSION_COUNT,
MISSION_ACK and MISSION_CURRENT carry plan ids (opaque_id): the encoder cuts each
payload to the length the dialect gives it. Nothing here allocates once a transfer
has started.

    missions = ep.services["missions"]
    missions.store(0|1|2)       the MissionStore of a plan type
    missions.runner             mission_runner.MissionRunner: what the application flies
    missions.allow(command, required=0)   a MAV_CMD the application can fly (see _RULES)
    missions.on_plan(mission_type)        hook: a new plan of that type is in force
"""
from ..compat import const, ticks_ms, ticks_diff, ticks_add
from ..fields import u16, i16, i32, f32_is_nan, f32_to_int
from ..kernels import copy
from ..mission_store import MissionStore, RECORD_SIZE
from ..mission_runner import MissionRunner

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
ACCEPTED = const(0)
ERROR = const(1)
UNSUPPORTED_FRAME = const(2)
UNSUPPORTED = const(3)
NO_SPACE = const(4)
INVALID = const(5)
INVALID_PARAM1 = const(6)
INVALID_PARAM5_X = const(10)
INVALID_PARAM6_Y = const(11)
INVALID_PARAM7 = const(12)
INVALID_SEQUENCE = const(13)
DENIED = const(14)
OPERATION_CANCELLED = const(15)

_TYPE_MISSION = const(0)
_TYPE_ALL = const(255)
_CMD_DO_JUMP = const(177)
_CMD_DO_SET_MISSION_CURRENT = const(224)
_CMD_MISSION_START = const(300)
_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_FAILED = const(4)

_IDLE = const(0)
_UPLOAD = const(1)
_DOWNLOAD = const(2)

_CAP_MISSION_FLOAT = const(1)
_CAP_MISSION_INT = const(4)
_CAP_MISSION_FENCE = const(16384)
_CAP_MISSION_RALLY = const(32768)

_NOT_A_NUMBER = const(-0x80000001)  # from _to_fixed: NaN, infinite or beyond int32
_ITEM_FRAME_BYTES = const(50)  # a MAVLink 2 MISSION_ITEM_INT, for pacing pushed items
_PUSH_SHARE = const(2)  # pushed items use at most 1/2 of the link
_CURRENT_PERIOD_MS = const(1000)

# What each command needs, by MAV_MISSION_TYPE: bits 0-3 param1-4 must be numbers,
# bit 6 z (param7) must be a number, _POS: x/y are a position (range-checked in
# global frames, not allowed in MAV_FRAME_MISSION).
_P1 = const(1)
_P2 = const(2)
_P7 = const(64)
_POS = const(128)
_RULES = (
    {  # mission: the seed's NAV, CONDITION and DO commands
        16: _POS | _P7,  # NAV_WAYPOINT
        17: _POS | _P7,  # NAV_LOITER_UNLIM
        18: _POS | _P7 | _P1,  # NAV_LOITER_TURNS
        19: _POS | _P7 | _P1,  # NAV_LOITER_TIME
        20: 0,  # NAV_RETURN_TO_LAUNCH
        21: _POS,  # NAV_LAND (z: NaN lands at ground level)
        22: _POS | _P7,  # NAV_TAKEOFF
        80: 0,  # NAV_ROI
        81: 0,  # NAV_PATHPLANNING
        112: _P1,  # CONDITION_DELAY
        113: _P1 | _P7,  # CONDITION_CHANGE_ALT
        114: _P1,  # CONDITION_DISTANCE
        115: _P1,  # CONDITION_YAW
        176: _P1,  # DO_SET_MODE
        177: _P1 | _P2,  # DO_JUMP
        178: _P2,  # DO_CHANGE_SPEED
        179: _P1,  # DO_SET_HOME
        180: _P1 | _P2,  # DO_SET_PARAMETER
        181: _P1 | _P2,  # DO_SET_RELAY
        182: _P1 | _P2,  # DO_REPEAT_RELAY
        183: _P1 | _P2,  # DO_SET_SERVO
        184: _P1 | _P2,  # DO_REPEAT_SERVO
        200: 0,  # DO_CONTROL_VIDEO
    },
    {  # fence
        5000: _POS,  # NAV_FENCE_RETURN_POINT
        5001: _POS | _P1,  # NAV_FENCE_POLYGON_VERTEX_INCLUSION (param1: vertex count)
        5002: _POS | _P1,  # NAV_FENCE_POLYGON_VERTEX_EXCLUSION
        5003: _POS | _P1,  # NAV_FENCE_CIRCLE_INCLUSION (param1: radius)
        5004: _POS | _P1,  # NAV_FENCE_CIRCLE_EXCLUSION
    },
    {  # rally
        5100: _POS | _P7,  # NAV_RALLY_POINT
    },
)
_LOCAL_FRAMES = (1, 4, 7, 8, 9, 12, 20, 21)  # x, y in metres (1e4 in MISSION_ITEM_INT)
_FRAME_MISSION = const(2)


class Missions:
    NAME = "missions"

    def __init__(self, capacities=(500, 100, 20), frames=(0, 2, 3, 5, 6), retry_ms=250,
                 retries=5, timeout_ms=5000, jump_slots=16, commands=()):
        self.capacities = capacities
        self.frames = frames
        self.retry_ms = retry_ms
        self.retries = retries
        self.timeout_ms = timeout_ms
        self.jump_slots = jump_slots
        self.rules = (dict(_RULES[0]), dict(_RULES[1]), dict(_RULES[2]))
        for command in commands:
            self.allow(command)
        self.on_plan = None
        self.stores = None
        self._rec = bytearray(RECORD_SIZE)
        # The transfer under way (one at a time).
        self.state = _IDLE
        self.t_link = None  # the peer: link, system and component
        self.t_sys = 0
        self.t_comp = 0
        self.t_type = 0
        self.t_store = None
        self.t_count = 0  # items in the plan once this upload is done / being read
        self.t_seq = 0  # upload: next item expected; download: next to push
        self.t_end = 0  # last item of this transfer
        self.t_int = True  # request MISSION_REQUEST_INT (else the seed's MISSION_REQUEST)
        self.t_v2 = True  # the peer speaks MAVLink 2
        self.t_current = -1  # upload: the item sent with current=1
        self.t_sent = 0  # ticks of the last request
        self.t_heard = 0  # ticks of the last frame from the peer
        self.t_tries = 0
        self.t_push = False  # download: pushing a partial list
        self.t_credit = 0
        # The last upload that completed, to answer a repeat of its final item.
        self.done_link = None
        self.done_sys = -1
        self.done_comp = -1
        self.done_type = 0
        self.done_seq = -1
        self._current_due = 0
        self._current_now = False
        self.uploads = 0  # completed transfers, for tests and statistics
        self.downloads = 0
        self.cancelled = 0

    def allow(self, command, required=0, mission_type=0):
        """Accept a MAV_CMD in uploaded plans (required: _RULES bits)."""
        self.rules[mission_type][command] = required

    def store(self, mission_type):
        return self.stores[mission_type]

    # --- wiring -------------------------------------------------------------------
    def attach(self, ep):
        self.ep = ep
        storage = ep.storage
        names = ("mission", "fence", "rally")
        self.stores = [MissionStore(storage, names[i], i, self.capacities[i]) for i in range(3)]
        for s in self.stores:
            if s.corrupt:
                ep.statustext(3, "Stored %s plan corrupt: cleared" % s.name)  # MAV_SEVERITY_ERROR
        self.runner = MissionRunner(self, self.jump_slots)
        # MISSION_ITEM_INT and MISSION_REQUEST_INT exist in today's dialect, not the seed's
        # (where id 51 is another message).
        self.has_int = ep.has(_MSG_ITEM_INT) and ep.fmt(_MSG_ITEM_INT).startswith("<ffffiif") \
            and ep.has(_MSG_REQUEST_INT) and ep.fmt(_MSG_REQUEST_INT).startswith("<HBB")
        # Extension fields present in this dialect (payload lengths of the MAVLink 2 forms).
        self.has_type = (ep.dialect.CRC_LEN.get(_MSG_COUNT, 0) >> 16) >= 5
        ep.on(_MSG_COUNT, self._on_count)
        ep.on(_MSG_ITEM, self._on_item)
        ep.on(_MSG_REQUEST_LIST, self._on_request_list)
        ep.on(_MSG_REQUEST, self._on_request)
        ep.on(_MSG_REQUEST_PARTIAL_LIST, self._on_request_partial)
        ep.on(_MSG_WRITE_PARTIAL_LIST, self._on_write_partial)
        ep.on(_MSG_CLEAR_ALL, self._on_clear_all)
        ep.on(_MSG_SET_CURRENT, self._on_set_current)
        ep.on(_MSG_ACK, self._on_ack)
        if self.has_int:
            ep.on(_MSG_ITEM_INT, self._on_item_int)
            ep.on(_MSG_REQUEST_INT, self._on_request_int)
            ep.capabilities |= _CAP_MISSION_INT
        ep.capabilities |= _CAP_MISSION_FLOAT
        if self.has_type:
            ep.capabilities |= _CAP_MISSION_FENCE | _CAP_MISSION_RALLY
        ep.producers[_MSG_CURRENT] = self.send_current
        ep.commands[_CMD_DO_SET_MISSION_CURRENT] = self._cmd_set_current
        ep.commands[_CMD_MISSION_START] = self._cmd_mission_start
        self._current_due = ticks_ms()

    # --- periodic work ------------------------------------------------------------
    def tick(self, now):
        state = self.state
        if state == _UPLOAD:
            if ticks_diff(now, self.t_sent) >= self.retry_ms:
                if self.t_tries >= self.retries or ticks_diff(now, self.t_heard) >= self.timeout_ms:
                    self._cancel()
                else:
                    self.t_tries += 1
                    self._request(self.t_seq)
        elif state == _DOWNLOAD:
            if self.t_push:
                self._push(now)
            if ticks_diff(now, self.t_heard) >= self.timeout_ms:
                self.state = _IDLE  # the ground station went away; nothing to undo
        # On change, and once a second (like HEARTBEAT, not left to the streams service).
        if self._current_now or ticks_diff(now, self._current_due) >= 0:
            for link in self.ep.links:
                self.send_current(link)
            self._current_now = False
            self._current_due = ticks_add(now, _CURRENT_PERIOD_MS)

    def current_changed(self):
        """Send MISSION_CURRENT on the next tick (the runner calls this)."""
        self._current_now = True

    # --- helpers --------------------------------------------------------------------
    def _type_of(self, link, mission_type):
        """The store for a request's mission_type, or None after answering UNSUPPORTED."""
        if mission_type == _TYPE_MISSION or (mission_type < 3 and link.version == 2 and self.has_type):
            return self.stores[mission_type]
        rx = link.rx
        self._ack(link, rx.sysid, rx.compid, UNSUPPORTED, mission_type)
        return None

    def _is_peer(self, link):
        rx = link.rx
        return link is self.t_link and rx.sysid == self.t_sys and rx.compid == self.t_comp

    def _busy_for(self, link, mission_type):
        """True (after answering DENIED) when another peer's transfer is under way."""
        if self.state == _IDLE or self._is_peer(link):
            return False
        rx = link.rx
        self._ack(link, rx.sysid, rx.compid, DENIED, mission_type)
        return True

    def _start(self, link, state, store, count):
        rx = link.rx
        self.state = state
        self.t_link = link
        self.t_sys = rx.sysid
        self.t_comp = rx.compid
        self.t_type = store.mission_type
        self.t_store = store
        self.t_count = count
        self.t_v2 = rx.version == 2
        self.t_int = self.has_int and self.t_v2
        self.t_current = -1
        self.t_tries = 0
        self.t_push = False
        now = ticks_ms()
        self.t_heard = now
        self.t_sent = now
        self.done_seq = -1

    def _cancel(self):
        self.cancelled += 1
        self.state = _IDLE
        self._ack(self.t_link, self.t_sys, self.t_comp, OPERATION_CANCELLED if self.t_v2 else ERROR,
                  self.t_type)

    # --- upload ---------------------------------------------------------------------
    def _on_count(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        rx = link.rx
        if not self.ep.allows(link):
            self._ack(link, rx.sysid, rx.compid, DENIED, p[4])
            return
        if self._busy_for(link, p[4]):
            return
        store = self._type_of(link, p[4])
        if store is None:
            return
        count = u16(p, 0)
        if self.state == _UPLOAD and self.t_store is store and self.t_seq > 0 and count == self.t_count \
                and self.t_end == count - 1:
            return  # a late copy of the MISSION_COUNT that started this upload
        self.state = _IDLE
        if count > store.capacity:
            self._ack(link, rx.sysid, rx.compid, NO_SPACE, store.mission_type)
            return
        if count == 0:
            self._ack(link, rx.sysid, rx.compid, self._clear(store), store.mission_type)
            return
        self._start(link, _UPLOAD, store, count)
        self.t_seq = 0
        self.t_end = count - 1
        store.begin()
        self._request(0)

    def _on_write_partial(self, link, p):
        if not self.ep.for_us(p[4], p[5]):
            return
        rx = link.rx
        if not self.ep.allows(link):
            self._ack(link, rx.sysid, rx.compid, DENIED, p[6])
            return
        if self._busy_for(link, p[6]):
            return
        store = self._type_of(link, p[6])
        if store is None:
            return
        start = i16(p, 0)
        end = i16(p, 2)
        # The seed: a start beyond the current list is rejected (0 always starts a list).
        if start < 0 or end < start or (start > 0 and start >= store.count):
            self._ack(link, rx.sysid, rx.compid, INVALID_SEQUENCE, store.mission_type)
            return
        count = end + 1 if end + 1 > store.count else store.count
        if count > store.capacity:
            self._ack(link, rx.sysid, rx.compid, NO_SPACE, store.mission_type)
            return
        self._start(link, _UPLOAD, store, count)
        self.t_seq = start
        self.t_end = end
        store.begin(store.count)
        self._request(start)

    def _request(self, seq):
        link = self.t_link
        off = link.begin()
        buf = link.txbuf
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        buf[off + 2] = self.t_sys
        buf[off + 3] = self.t_comp
        buf[off + 4] = self.t_type
        link.send(_MSG_REQUEST_INT if self.t_int else _MSG_REQUEST)
        self.t_sent = ticks_ms()

    def _on_item_int(self, link, p):
        self._item(link, p, True)

    def _on_item(self, link, p):
        self._item(link, p, False)

    def _item(self, link, p, is_int):
        if not self.ep.for_us(p[32], p[33]):
            return
        seq = u16(p, 28)
        if self.state != _UPLOAD or not self._is_peer(link):
            rx = link.rx
            # The ACK of a completed upload was lost: the ground station repeats the last item.
            if (self.state == _IDLE and seq == self.done_seq and link is self.done_link
                    and rx.sysid == self.done_sys and rx.compid == self.done_comp and p[37] == self.done_type):
                self._ack(link, rx.sysid, rx.compid, ACCEPTED, self.done_type)
            return
        if p[37] != self.t_type:
            return
        self.t_heard = ticks_ms()
        if seq != self.t_seq:
            # Out of sequence: ignored. A copy of the previous item (a duplicate, or
            # one that crossed our re-request) waits for the retry timer, so that
            # duplicates cannot breed more duplicates; anything else is re-requested now.
            if seq + 1 != self.t_seq:
                self._request(self.t_seq)
            return
        if not is_int:
            self.t_int = False  # it speaks the seed's messages: ask in its terms
        result = self._check(p, is_int, seq)
        if result != ACCEPTED:
            self.state = _IDLE
            self._ack(link, self.t_sys, self.t_comp, result, self.t_type)
            return
        store = self.t_store
        if not store.put(seq, self._rec):
            self.state = _IDLE
            self._ack(link, self.t_sys, self.t_comp, ERROR, self.t_type)
            return
        if p[35] == 1:
            self.t_current = seq
        if seq < self.t_end:
            self.t_seq = seq + 1
            self.t_tries = 0
            self._request(seq + 1)
            return
        self.state = _IDLE
        result = self._commit(store, self.t_count)
        if result == ACCEPTED:
            self.uploads += 1
            self.done_link = link
            self.done_sys = self.t_sys
            self.done_comp = self.t_comp
            self.done_type = self.t_type
            self.done_seq = seq
            self._plan_changed(store, self.t_current)
        self._ack(link, self.t_sys, self.t_comp, result, self.t_type)

    def _commit(self, store, count):
        if not store.seal(count):
            return ERROR
        if store.mission_type == _TYPE_MISSION and store.staged_jumps > self.jump_slots:
            return NO_SPACE  # more DO_JUMPs than the runner keeps counters for
        return ACCEPTED if store.commit() else ERROR

    def _clear(self, store):
        store.begin()
        result = self._commit(store, 0)
        if result == ACCEPTED:
            self._plan_changed(store, 0)
        return result

    def _plan_changed(self, store, current):
        if store.mission_type == _TYPE_MISSION:
            self.runner.plan_changed(current)
        self.current_changed()
        if self.on_plan is not None:
            self.on_plan(store.mission_type)

    def _check(self, p, is_int, seq):
        """Validate an item and build its record in self._rec -> MAV_MISSION_RESULT."""
        rec = self._rec
        copy(rec, p, 0, 28)  # params, x, y, z as they came
        rec[28] = p[30]
        rec[29] = p[31]
        frame = p[34]
        rec[30] = frame
        rec[31] = p[36]
        command = u16(p, 30)
        if frame not in self.frames:
            return UNSUPPORTED_FRAME
        need = self.rules[self.t_type].get(command)
        if need is None:
            return UNSUPPORTED
        local = frame in _LOCAL_FRAMES
        pos = need & _POS
        if pos and frame == _FRAME_MISSION:
            return UNSUPPORTED_FRAME
        if not is_int:
            scale_e = 4 if local else 7
            x = _to_fixed(p, 16, scale_e)
            y = _to_fixed(p, 20, scale_e)
            if x == _NOT_A_NUMBER:
                if pos:
                    return INVALID_PARAM5_X
                x = 0
            if y == _NOT_A_NUMBER:
                if pos:
                    return INVALID_PARAM6_Y
                y = 0
            _put_i32(rec, 16, x)
            _put_i32(rec, 20, y)
        if pos and not local:
            if not -900000000 <= i32(rec, 16) <= 900000000:
                return INVALID_PARAM5_X
            if not -1800000000 <= i32(rec, 20) <= 1800000000:
                return INVALID_PARAM6_Y
        for i in range(4):
            if need & (1 << i) and f32_is_nan(p, i * 4):
                return INVALID_PARAM1 + i
        if need & _P7 and f32_is_nan(p, 24):
            return INVALID_PARAM7
        if command == _CMD_DO_JUMP:
            target = f32_to_int(p, 0)
            if target < 0 or target >= self.t_count or target == seq:
                return INVALID_PARAM1
            if f32_to_int(p, 4) < -1:
                return INVALID_PARAM1 + 1
        return ACCEPTED

    # --- download -------------------------------------------------------------------
    def _on_request_list(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        if self._busy_for(link, p[2]):
            return
        store = self._type_of(link, p[2])
        if store is None:
            return
        self.state = _IDLE
        if store.count:
            self._start(link, _DOWNLOAD, store, store.count)
            self.t_end = store.count - 1
        rx = link.rx
        self._send_count(link, rx.sysid, rx.compid, store)

    def _on_request_partial(self, link, p):
        if not self.ep.for_us(p[4], p[5]):
            return
        if self._busy_for(link, p[6]):
            return
        store = self._type_of(link, p[6])
        if store is None:
            return
        start = i16(p, 0)
        end = i16(p, 2)
        if end < 0 or end >= store.count:
            end = store.count - 1  # -1: to the end of the list
        self.state = _IDLE
        if start < 0 or start > end:
            rx = link.rx
            self._ack(link, rx.sysid, rx.compid, INVALID_SEQUENCE, store.mission_type)
            return
        self._start(link, _DOWNLOAD, store, store.count)
        self.t_seq = start
        self.t_end = end
        self.t_push = True
        self.t_credit = _ITEM_FRAME_BYTES
        self._push(self.t_sent)

    def _push(self, now):
        # Items of a partial list go out at a share of the link's capacity.
        link = self.t_link
        elapsed = ticks_diff(now, self.t_sent)
        if elapsed > 0:
            self.t_sent = now
            self.t_credit += elapsed * link.bytes_per_s // (1000 * _PUSH_SHARE)
            if self.t_credit > 4 * _ITEM_FRAME_BYTES:
                self.t_credit = 4 * _ITEM_FRAME_BYTES
        while self.t_credit >= _ITEM_FRAME_BYTES and self.t_seq <= self.t_end:
            self.t_credit -= _ITEM_FRAME_BYTES
            self._send_item(link, self.t_store, self.t_seq, self.t_int)
            self.t_seq += 1
        if self.t_seq > self.t_end:
            self.t_push = False
            self.state = _IDLE
            self.downloads += 1

    def _on_request_int(self, link, p):
        self._request_item(link, p, True)

    def _on_request(self, link, p):
        self._request_item(link, p, False)

    def _request_item(self, link, p, as_int):
        if not self.ep.for_us(p[2], p[3]):
            return
        rx = link.rx
        if self.state == _UPLOAD or (self.state == _DOWNLOAD and not self._is_peer(link)):
            if not self._is_peer(link):
                self._ack(link, rx.sysid, rx.compid, DENIED, p[4])
            return
        if p[4] > 2 or (p[4] and link.version == 1):
            self._ack(link, rx.sysid, rx.compid, UNSUPPORTED, p[4])
            return
        store = self.stores[p[4]]
        seq = u16(p, 0)
        if seq >= store.count:
            self.state = _IDLE
            self._ack(link, rx.sysid, rx.compid, INVALID_SEQUENCE, store.mission_type)
            return
        self.t_heard = ticks_ms()
        self._send_item(link, store, seq, as_int)
        if self.state == _DOWNLOAD and seq == self.t_end and not self.t_push:
            self.state = _IDLE  # the last item: done, whether or not an ACK follows
            self.downloads += 1

    def _send_item(self, link, store, seq, as_int):
        rec = self._rec
        if not store.read(seq, rec):
            return False
        off = link.begin()
        buf = link.txbuf
        copy(buf, rec, off, 28)
        if not as_int:
            scale_e = 4 if rec[30] in _LOCAL_FRAMES else 7
            _put_u32(buf, off + 16, _to_float(i32(rec, 16), scale_e))
            _put_u32(buf, off + 20, _to_float(i32(rec, 20), scale_e))
        buf[off + 28] = seq & 0xFF
        buf[off + 29] = seq >> 8
        buf[off + 30] = rec[28]
        buf[off + 31] = rec[29]
        buf[off + 32] = link.rx.sysid
        buf[off + 33] = link.rx.compid
        buf[off + 34] = rec[30]
        buf[off + 35] = 1 if store.mission_type == _TYPE_MISSION and seq == self.runner.current else 0
        buf[off + 36] = rec[31]
        buf[off + 37] = store.mission_type
        return link.send(_MSG_ITEM_INT if as_int else _MSG_ITEM)

    def _send_count(self, link, sysid, compid, store):
        off = link.begin()
        buf = link.txbuf
        count = store.count
        buf[off] = count & 0xFF
        buf[off + 1] = count >> 8
        buf[off + 2] = sysid
        buf[off + 3] = compid
        buf[off + 4] = store.mission_type
        _put_u32(buf, off + 5, store.plan_id)  # opaque_id, where the dialect has it
        return link.send(_MSG_COUNT)

    def _on_ack(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        if self.state != _IDLE and self._is_peer(link) and p[3] == self.t_type:
            # The ground station ends the download, or cancels its upload: nothing is stored.
            if self.state == _DOWNLOAD:
                self.downloads += 1
            self.state = _IDLE

    # --- clear, current -------------------------------------------------------------
    def _on_clear_all(self, link, p):
        if not self.ep.for_us(p[0], p[1]):
            return
        rx = link.rx
        mission_type = p[2]
        if not self.ep.allows(link):
            self._ack(link, rx.sysid, rx.compid, DENIED, mission_type)
            return
        if self._busy_for(link, mission_type):
            return
        self.state = _IDLE
        if mission_type == _TYPE_ALL and (link.version == 2 or not self.has_type):
            result = ACCEPTED
            for store in self.stores:
                r = self._clear(store)
                if r != ACCEPTED:
                    result = r
        else:
            store = self._type_of(link, mission_type)
            if store is None:
                return
            result = self._clear(store)
        self._ack(link, rx.sysid, rx.compid, result, mission_type)

    def _on_set_current(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        if self.ep.allows(link) and self.runner.set_current(u16(p, 0)):
            return  # MISSION_CURRENT follows from the change
        self.ep.statustext(4, "Mission: cannot set current item")  # MAV_SEVERITY_WARNING
        self.send_current(link)

    def _cmd_set_current(self, cmd):
        if not self.ep.allows(cmd.link):
            return _RESULT_DENIED
        seq = -1 if cmd.nan(1) else cmd.int(1)
        reset = not cmd.nan(2) and cmd.int(2) == 1
        if seq < 0 and not reset:
            return _RESULT_ACCEPTED
        if seq < 0:
            seq = self.runner.current
        return _RESULT_ACCEPTED if self.runner.set_current(seq, reset) else _RESULT_FAILED

    def _cmd_mission_start(self, cmd):
        if not self.ep.allows(cmd.link):
            return _RESULT_DENIED
        first = 0 if cmd.nan(1) else cmd.int(1)
        last = -1 if cmd.nan(2) else cmd.int(2)
        return _RESULT_ACCEPTED if self.runner.start(first, last) else _RESULT_FAILED

    def send_current(self, link):
        runner = self.runner
        store = self.stores[_TYPE_MISSION]
        off = link.begin()
        buf = link.txbuf
        seq = runner.current
        total = store.count if store.count else 0xFFFF
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        buf[off + 2] = total & 0xFF
        buf[off + 3] = total >> 8
        buf[off + 4] = runner.state
        buf[off + 5] = runner.mode
        _put_u32(buf, off + 6, store.plan_id)  # mission_id, fence_id, rally_points_id
        _put_u32(buf, off + 10, self.stores[1].plan_id)
        _put_u32(buf, off + 14, self.stores[2].plan_id)
        return link.send(_MSG_CURRENT)

    def send_reached(self, seq):
        for link in self.ep.links:
            off = link.begin()
            buf = link.txbuf
            buf[off] = seq & 0xFF
            buf[off + 1] = seq >> 8
            link.send(_MSG_ITEM_REACHED)

    def _ack(self, link, sysid, compid, result, mission_type):
        store = self.stores[mission_type] if mission_type < 3 else None
        off = link.begin()
        buf = link.txbuf
        buf[off] = sysid
        buf[off + 1] = compid
        buf[off + 2] = result
        buf[off + 3] = mission_type
        _put_u32(buf, off + 4, store.plan_id if store is not None and result == ACCEPTED else 0)  # opaque_id
        link.send(_MSG_ACK)


def _put_u32(buf, o, v):
    buf[o] = v & 0xFF
    buf[o + 1] = (v >> 8) & 0xFF
    buf[o + 2] = (v >> 16) & 0xFF
    buf[o + 3] = (v >> 24) & 0xFF


def _put_i32(buf, o, v):
    _put_u32(buf, o, v & 0xFFFFFFFF)


def _to_fixed(p, o, scale_e):
    """A float32 field times 10**scale_e, rounded to the nearest int, from its bits.

    MISSION_ITEM carries degrees (metres in local frames) as floats; the store keeps
    MISSION_ITEM_INT's integers. The float is m * 2**(e-150) exactly, so
    m * 10**scale_e shifted by e-150 with rounding is the exact nearest integer;
    no float is made. _NOT_A_NUMBER for NaN, infinities and values beyond int32.
    """
    b = p[o] | p[o + 1] << 8 | p[o + 2] << 16 | p[o + 3] << 24
    e = (b >> 23) & 0xFF
    # |f| >= 2**(e-127); beyond 2**31 / 10**scale_e it cannot fit an int32 (and the
    # shift below stays negative, so the ints stay small).
    if e > (134 if scale_e == 7 else 144):
        return _NOT_A_NUMBER  # also NaN and the infinities (e == 0xFF)
    m = b & 0x7FFFFF
    if e:
        m |= 0x800000
    else:
        e = 1  # subnormal
    v = m * 10 ** scale_e
    shift = 150 - e
    v = (v + (1 << (shift - 1))) >> shift if shift < 62 else 0
    if v > 0x7FFFFFFF:
        return _NOT_A_NUMBER
    return -v if b & 0x80000000 else v


def _to_float(v, scale_e):
    """Bits of the float32 nearest to v / 10**scale_e (round half to even), from ints."""
    if v == 0:
        return 0
    sign = 0
    if v < 0:
        sign = 0x80000000
        v = -v
    d = 10 ** scale_e
    # Find s with 2**23 <= v * 2**s / d < 2**24, then round the quotient.
    s = 23
    while (v << s if s >= 0 else v >> -s) >= d << 24:
        s -= 1
    while (v << s if s >= 0 else v >> -s) < d << 23:
        s += 1
    n = v << s  # s >= 0 for every int32 v and d >= 10**4
    q = n // d
    r = n - q * d
    if 2 * r > d or (2 * r == d and q & 1):
        q += 1
    if q == 1 << 24:
        q >>= 1
        s -= 1
    return sign | (150 - s) << 23 | (q & 0x7FFFFF)


def create(ep):
    board = getattr(ep, "board", None)
    options = getattr(ep, "options", None) or {}

    def setting(name, default):
        return int(options.get(name.lower(), getattr(board, name, default)))

    missions = Missions(
        capacities=(setting("MISSION_CAPACITY", 500), setting("FENCE_CAPACITY", 100),
                    setting("RALLY_CAPACITY", 20)),
        frames=getattr(board, "MISSION_FRAMES", (0, 2, 3, 5, 6)),
        retry_ms=setting("MISSION_RETRY_MS", 250),
        retries=setting("MISSION_RETRIES", 5),
        timeout_ms=setting("MISSION_TIMEOUT_MS", 5000),
        jump_slots=setting("MISSION_JUMP_SLOTS", 16),
        commands=getattr(board, "MISSION_COMMANDS", ()),
    )
    return ep.add(missions)
