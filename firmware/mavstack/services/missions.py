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
    missions.stores[0|1|2]      the MissionStore of each plan type (None for a capacity of
                                0: a board without geofence or rally points)
    missions.runner             mission_runner.MissionRunner, what the application flies
                                (None on a board with MISSION_RUNNER = False: plans are
                                kept and served, MISSION_START is UNSUPPORTED)
    missions.allow(command, need=0)   a MAV_CMD the application flies (need: _P*/_POS bits)
"""
import gc

from ..compat import const, ticks_diff, ticks_add
from ..fields import u16, i16, i32, f32_is_nan, f32_to_int
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

_NOT_A_NUMBER = const(-0x80000001)  # from _to_fixed: NaN, infinite or beyond int32
_ITEM_FRAME_BYTES = const(50)  # a MAVLink 2 MISSION_ITEM_INT, for pacing pushed items
_PUSH_SHARE = const(2)  # pushed items use at most 1/2 of the link
_CURRENT_PERIOD_MS = const(1000)
_FRAME_MISSION = const(2)

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

    def __init__(self, storage, capacities=(500, 100, 20), frames=(0, 2, 3, 5, 6), retry_ms=250,
                 retries=5, timeout_ms=5000, jump_slots=16, commands=()):
        # (Few attributes: on a small heap a bigger instance dict may not find room.)
        self.stores = [MissionStore(storage, _NAMES[t], t, capacities[t]) if capacities[t] or t == 0 else None
                       for t in range(3)]
        self.frames = frames
        self.retry_ms = retry_ms
        self.retries = retries
        self.timeout_ms = timeout_ms
        self.jump_slots = jump_slots
        self.extra = None  # {command: need} the application added to the mission rules
        for command in commands:
            self.allow(command)
        self.runner = None
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
        self.done_key = -1  # link index << 24 | sysid << 16 | compid << 8 | mission_type
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
        for msgid, handler in ((_MSG_COUNT, self._on_count), (_MSG_WRITE_PARTIAL_LIST, self._on_write_partial),
                               (_MSG_ITEM, self._on_item), (_MSG_REQUEST_LIST, self._on_request_list),
                               (_MSG_REQUEST_PARTIAL_LIST, self._on_request_partial),
                               (_MSG_REQUEST, self._on_request), (_MSG_CLEAR_ALL, self._on_clear_all),
                               (_MSG_SET_CURRENT, self._on_set_current), (_MSG_ACK, self._on_ack)):
            ep.on(msgid, handler)
        ep.capabilities |= _CAP_MISSION_FLOAT
        if self.has_int:
            ep.on(_MSG_ITEM_INT, self._on_item)
            ep.on(_MSG_REQUEST_INT, self._on_request)
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
            if self.t_tries >= self.retries or ticks_diff(now, self.t_heard) >= self.timeout_ms:
                self.state = _IDLE
                self._ack(self.t_link, self.t_peer >> 8, self.t_peer & 0xFF,
                          _OPERATION_CANCELLED if self.t_link.version == 2 else _ERROR,
                          self.t_store.mission_type)
            else:
                self.t_tries += 1
                self._request(self.t_seq)
        elif state == _PUSH:
            self._push(now)
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

    def current_changed(self):
        """Send MISSION_CURRENT on the next tick (the runner calls this)."""
        self._current_changed = True

    # --- starting a transfer ------------------------------------------------------
    def _is_peer(self, link):
        rx = link.rx
        return link is self.t_link and rx.sysid << 8 | rx.compid == self.t_peer

    def _type(self, p, o):
        """The mission_type extension field at offset o (0 where the dialect has none:
        the payload view holds stale bytes past a message's length)."""
        return p[o] if self.has_type else 0

    def _open(self, link, p, at, mission_type, change, every=False):
        """Checks shared by the requests that start something -> the plan type, or -1
        once refused. at: offset of target_system; change: needs operator control;
        every: MAV_MISSION_TYPE_ALL (255) is allowed (MISSION_CLEAR_ALL)."""
        if not self.ep.for_us(p[at], p[at + 1]):
            return -1
        rx = link.rx
        if change and not self.ep.allows(link):
            result = _DENIED
        elif self.state != _IDLE and not self._is_peer(link):
            result = _DENIED  # one transfer at a time; the one under way goes on
        elif mission_type == _TYPE_MISSION or (mission_type < 3 and link.version == 2 and self.has_type
                                               and self.stores[mission_type] is not None):
            self.state = _IDLE  # the peer starts over: whatever it had under way is dropped
            return mission_type
        elif mission_type == _TYPE_ALL and every:
            self.state = _IDLE
            return mission_type
        else:
            result = _UNSUPPORTED  # fence and rally need MAVLink 2
        self._ack(link, rx.sysid, rx.compid, result, mission_type)
        return -1

    def _start(self, link, state, store, seq, end):
        rx = link.rx
        self.state = state
        self.t_link = link
        self.t_peer = rx.sysid << 8 | rx.compid
        self.t_store = store
        self.t_seq = seq
        self.t_end = end
        self.t_int = self.has_int and rx.version == 2
        self.t_tries = 0
        now = self.ep.now
        self.t_heard = now
        self.t_sent = now
        self.done_seq = -1

    # --- upload -------------------------------------------------------------------
    def _on_count(self, link, p):
        count = u16(p, 0)
        mt = self._type(p, 4)
        if (self.state == _UPLOAD and self._is_peer(link) and self.t_seq > 0 and count == self.t_count
                and self.t_end == count - 1 and mt == self.t_store.mission_type):
            return  # a late copy of the MISSION_COUNT that started this upload
        mt = self._open(link, p, 2, mt, True)
        if mt < 0:
            return
        store = self.stores[mt]
        rx = link.rx
        if count > store.capacity:
            self._ack(link, rx.sysid, rx.compid, _NO_SPACE, mt)
        elif count == 0:
            self._ack(link, rx.sysid, rx.compid, self._clear(store), mt)
        else:
            self._upload(link, store, count, 0, count - 1, 0)

    def _on_write_partial(self, link, p):
        mt = self._open(link, p, 4, self._type(p, 6), True)
        if mt < 0:
            return
        store = self.stores[mt]
        start = i16(p, 0)
        end = i16(p, 2)
        count = end + 1 if end + 1 > store.count else store.count
        rx = link.rx
        # The seed: a start beyond the current list is rejected (0 always starts a list).
        if start < 0 or end < start or (start > 0 and start >= store.count):
            self._ack(link, rx.sysid, rx.compid, _INVALID_SEQUENCE, mt)
        elif count > store.capacity:
            self._ack(link, rx.sysid, rx.compid, _NO_SPACE, mt)
        else:
            self._upload(link, store, count, start, end, store.count)

    def _upload(self, link, store, count, start, end, keep):
        self._start(link, _UPLOAD, store, start, end)
        self.t_count = count
        self.t_current = -1 if start == 0 and keep == 0 else -2
        store.begin(keep)
        self._request(start)

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
        seq = u16(p, 28)
        rx = link.rx
        mt = self._type(p, 37)
        if self.state != _UPLOAD or not self._is_peer(link):
            # The ACK of a completed upload was lost: the ground station repeats the last item.
            if (self.state == _IDLE and seq == self.done_seq
                    and link.index << 24 | rx.sysid << 16 | rx.compid << 8 | mt == self.done_key):
                self._ack(link, rx.sysid, rx.compid, _ACCEPTED, mt)
            return
        store = self.t_store
        if mt != store.mission_type:
            return
        self.t_heard = self.ep.now
        if seq != self.t_seq:
            # Out of sequence: ignored. A copy of the previous item (a duplicate, or one
            # that crossed our re-request) waits for the retry timer, so that duplicates
            # cannot breed more duplicates; anything else has the expected one re-requested.
            if seq + 1 != self.t_seq:
                self._request(self.t_seq)
            return
        is_int = rx.msgid == _MSG_ITEM_INT
        if not is_int:
            self.t_int = False  # it speaks the seed's messages: ask in its terms
        result = self._check(p, is_int, seq)
        if result == _ACCEPTED and not store.put(seq, self._rec):
            result = _ERROR
        if result != _ACCEPTED:
            self.state = _IDLE
            self._ack(link, rx.sysid, rx.compid, result, mt)
            return
        if p[35] == 1 and self.t_current != -2:
            self.t_current = seq
        if seq < self.t_end:
            self.t_seq = seq + 1
            self.t_tries = 0
            self._request(seq + 1)
            return
        self.state = _IDLE
        result = self._commit(store, self.t_count)
        if result == _ACCEPTED:
            self.done_key = link.index << 24 | self.t_peer << 8 | mt
            self.done_seq = seq
            self._plan_changed(store, 0 if self.t_current == -1 else self.t_current)  # -2: keep
        self._ack(link, rx.sysid, rx.compid, result, mt)

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
        rec = self._rec
        copy(rec, p, 0, 28)  # params, x, y, z as they came
        rec[28] = p[30]
        rec[29] = p[31]
        frame = p[34]
        rec[30] = frame
        rec[31] = p[36]
        command = u16(p, 30)
        if frame not in self.frames:
            return _UNSUPPORTED_FRAME
        mt = self.t_store.mission_type
        need = _need(_RULES[mt], command)
        if need < 0 and mt == _TYPE_MISSION and self.extra is not None:
            need = self.extra.get(command, -1)
        if need < 0:
            return _UNSUPPORTED
        local = frame in _LOCAL_FRAMES
        pos = need & _POS
        if pos and frame == _FRAME_MISSION:
            return _UNSUPPORTED_FRAME
        if not is_int:
            scale_e = 4 if local else 7
            for i in range(2):
                v = _to_fixed(p, 16 + 4 * i, scale_e)
                if v == _NOT_A_NUMBER:
                    if pos:
                        return _INVALID_PARAM5_X + i
                    v = 0
                _put_u32(rec, 16 + 4 * i, v & 0xFFFFFFFF)
        if pos and not local:
            if not -900000000 <= i32(rec, 16) <= 900000000:
                return _INVALID_PARAM5_X
            if not -1800000000 <= i32(rec, 20) <= 1800000000:
                return _INVALID_PARAM6_Y
        for i in range(4):
            if need & (1 << i) and f32_is_nan(p, i * 4):
                return _INVALID_PARAM1 + i
        if need & _P7 and f32_is_nan(p, 24):
            return _INVALID_PARAM7
        if command == _CMD_DO_JUMP:
            target = f32_to_int(p, 0)
            if target < 0 or target >= self.t_count or target == seq:
                return _INVALID_PARAM1
            if f32_to_int(p, 4) < -1:
                return _INVALID_PARAM1 + 1
        return _ACCEPTED

    # --- download -----------------------------------------------------------------
    def _on_request_list(self, link, p):
        mt = self._open(link, p, 0, self._type(p, 2), False)
        if mt < 0:
            return
        store = self.stores[mt]
        count = store.count
        if count:
            self._start(link, _DOWNLOAD, store, 0, count - 1)
        rx = link.rx
        off = link.begin()
        buf = link.txbuf
        buf[off] = count & 0xFF
        buf[off + 1] = count >> 8
        buf[off + 2] = rx.sysid
        buf[off + 3] = rx.compid
        buf[off + 4] = mt
        _put_u32(buf, off + 5, store.plan_id)  # opaque_id, where the dialect has it
        link.send(_MSG_COUNT)

    def _on_request_partial(self, link, p):
        mt = self._open(link, p, 4, self._type(p, 6), False)
        if mt < 0:
            return
        store = self.stores[mt]
        start = i16(p, 0)
        end = i16(p, 2)
        if end < 0 or end >= store.count:
            end = store.count - 1  # -1: to the end of the list
        if start < 0 or start > end:
            rx = link.rx
            self._ack(link, rx.sysid, rx.compid, _INVALID_SEQUENCE, mt)
            return
        self._start(link, _PUSH, store, start, end)
        self.t_credit = _ITEM_FRAME_BYTES
        self._push(self.t_sent)

    def _push(self, now):
        # The items of a partial list go out at a share of the link's capacity.
        link = self.t_link
        elapsed = ticks_diff(now, self.t_sent)
        if elapsed > 0:
            self.t_sent = now
            credit = self.t_credit + elapsed * link.bytes_per_s // (1000 * _PUSH_SHARE)
            self.t_credit = credit if credit < 4 * _ITEM_FRAME_BYTES else 4 * _ITEM_FRAME_BYTES
        while self.t_credit >= _ITEM_FRAME_BYTES and self.t_seq <= self.t_end:
            self.t_credit -= _ITEM_FRAME_BYTES
            self._send_item(link, self.t_store, self.t_seq, self.t_int)
            self.t_seq += 1
        if self.t_seq > self.t_end:
            self.state = _IDLE

    def _on_request(self, link, p):
        # MISSION_REQUEST_INT is answered with MISSION_ITEM_INT, the seed's MISSION_REQUEST
        # with MISSION_ITEM; answered whenever no other ground station has a transfer open.
        if not self.ep.for_us(p[2], p[3]):
            return
        rx = link.rx
        mt = self._type(p, 4)
        state = self.state
        if state == _UPLOAD or (state != _IDLE and not self._is_peer(link)):
            if not self._is_peer(link):
                self._ack(link, rx.sysid, rx.compid, _DENIED, mt)
            return
        store = self.stores[mt] if mt < 3 and (mt == 0 or link.version == 2) else None
        if store is None:
            self._ack(link, rx.sysid, rx.compid, _UNSUPPORTED, mt)
            return
        seq = u16(p, 0)
        if seq >= store.count:
            self.state = _IDLE
            self._ack(link, rx.sysid, rx.compid, _INVALID_SEQUENCE, mt)
            return
        self.t_heard = self.ep.now
        self._send_item(link, store, seq, rx.msgid == _MSG_REQUEST_INT)
        if state == _DOWNLOAD and seq == self.t_end:
            self.state = _IDLE  # the last item: done, whether or not an ACK follows

    def _send_item(self, link, store, seq, as_int):
        rec = self._rec
        if not store.read(seq, rec):
            return
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
        runner = self.runner
        buf[off + 35] = 1 if store.mission_type == _TYPE_MISSION and runner is not None and seq == runner.current else 0
        buf[off + 36] = rec[31]
        buf[off + 37] = store.mission_type
        link.send(_MSG_ITEM_INT if as_int else _MSG_ITEM)

    def _on_ack(self, link, p):
        # The peer ends its download, or cancels its upload (nothing is stored then).
        if (self.ep.for_us(p[0], p[1]) and self.state != _IDLE and self._is_peer(link)
                and self._type(p, 3) == self.t_store.mission_type):
            self.state = _IDLE

    # --- clear, current -----------------------------------------------------------
    def _on_clear_all(self, link, p):
        mt = self._open(link, p, 0, self._type(p, 2), True, True)
        if mt < 0:
            return
        result = _ACCEPTED
        for store in self.stores:
            if store is not None and (mt == _TYPE_ALL or mt == store.mission_type):
                r = self._clear(store)
                if r != _ACCEPTED:
                    result = r
        rx = link.rx
        self._ack(link, rx.sysid, rx.compid, result, mt)

    def _on_set_current(self, link, p):
        if not self.ep.for_us(p[2], p[3]):
            return
        runner = self.runner
        if runner is not None and self.ep.allows(link) and runner.set_current(u16(p, 0)):
            return  # MISSION_CURRENT follows from the change
        self.ep.statustext(4, "Mission: cannot set current item")  # MAV_SEVERITY_WARNING
        self.send_current(link)

    def send_current(self, link):
        runner = self.runner
        stores = self.stores
        off = link.begin()
        buf = link.txbuf
        count = stores[0].count
        total = count or 0xFFFF  # UINT16_MAX: no mission
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
        buf[off + 2] = total & 0xFF
        buf[off + 3] = total >> 8
        for i in range(3):  # mission_id, fence_id, rally_points_id, where the dialect has them
            _put_u32(buf, off + 6 + 4 * i, stores[i].plan_id if stores[i] is not None else 0)
        return link.send(_MSG_CURRENT)

    def send_reached(self, seq):
        for link in self.ep.links:
            off = link.begin()
            link.txbuf[off] = seq & 0xFF
            link.txbuf[off + 1] = seq >> 8
            link.send(_MSG_ITEM_REACHED)

    def _ack(self, link, sysid, compid, result, mission_type):
        off = link.begin()
        buf = link.txbuf
        buf[off] = sysid
        buf[off + 1] = compid
        buf[off + 2] = result
        buf[off + 3] = mission_type
        # opaque_id (where the dialect has it): the new plan's id after an upload.
        store = self.stores[mission_type] if mission_type < 3 else None
        _put_u32(buf, off + 4, store.plan_id if result == _ACCEPTED and store is not None else 0)
        link.send(_MSG_ACK)


def _need(rules, command):
    for i in range(0, len(rules), 3):
        if rules[i] | rules[i + 1] << 8 == command:
            return rules[i + 2]
    return -1


def _put_u32(buf, o, v):
    buf[o] = v & 0xFF
    buf[o + 1] = (v >> 8) & 0xFF
    buf[o + 2] = (v >> 16) & 0xFF
    buf[o + 3] = (v >> 24) & 0xFF


def _to_fixed(p, o, scale_e):
    """A float32 field times 10**scale_e, rounded to the nearest int, from its bits.

    MISSION_ITEM carries degrees (metres in local frames) as floats; the store keeps
    MISSION_ITEM_INT's integers. The float is m * 2**(e-150) exactly, so
    m * 10**scale_e shifted right by 150-e with rounding is the exact nearest integer,
    and no float is made. _NOT_A_NUMBER for NaN, infinities and values beyond int32.
    """
    b = p[o] | p[o + 1] << 8 | p[o + 2] << 16 | p[o + 3] << 24
    e = (b >> 23) & 0xFF
    # |f| >= 2**(e-127): beyond 2**31 / 10**scale_e it cannot fit an int32. Below that
    # the shift stays negative, so every int here stays small.
    if e > (134 if scale_e == 7 else 144):
        return _NOT_A_NUMBER  # also NaN and the infinities (e == 255)
    m = b & 0x7FFFFF
    if e:
        m |= 0x800000
    else:
        e = 1  # subnormal
    shift = 150 - e
    v = (m * 10 ** scale_e + (1 << (shift - 1))) >> shift if shift < 62 else 0
    if v > 0x7FFFFFFF:
        return _NOT_A_NUMBER
    return -v if b & 0x80000000 else v


def _to_float(v, scale_e):
    """Bits of the float32 nearest to v / 10**scale_e (ties to even), from ints."""
    if v == 0:
        return 0
    sign = 0
    if v < 0:
        sign = 0x80000000
        v = -v
    d = 10 ** scale_e
    # s such that 2**23 <= v * 2**s / d < 2**24; s > 0 for any int32 v and d >= 10**4.
    s = 23
    while v << s >= d << 24:
        s -= 1
    while v << s < d << 23:
        s += 1
    n = v << s
    q = n // d
    r = n - q * d
    if 2 * r > d or (2 * r == d and q & 1):
        q += 1
        if q == 1 << 24:
            q >>= 1
            s -= 1
    return sign | (150 - s) << 23 | (q & 0x7FFFFF)


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
    return missions
