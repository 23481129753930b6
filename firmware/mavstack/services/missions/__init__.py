"""Mission protocol, vehicle side: mission, fence and rally plans, uploaded, downloaded,
cleared, partially read and written, with the current item and its progress. This
module is the service: it takes the messages and admits each request (its target, plan
type, operator control, and the transfer under way: transfer.py), commits uploaded
plans and sends MISSION_CURRENT, MISSION_ITEM_REACHED and MISSION_ACK. Beside it:
transfer.py (the one transfer under way, and the download), upload.py (the upload's
window), items.py (what an item must hold), store.py (plans in flash), rare.py (what a
ground station seldom sends, loaded on first use), runner.py (what the application
flies). Frames are written byte by byte at the payload offsets, so the same code serves
the seed's dialect and today's, whose messages carry plan ids and mission_type (an
extension field). Nothing here allocates once a transfer has started.
Reference: docs/services/missions.md.
"""
import gc

from ...compat import const, ticks_diff, ticks_add, to_grid
from ...fields import u16
from .store import MissionStore, RECORD_SIZE
from .transfer import CHANGE, EVERY, IDLE, PUSH, UPLOAD
from .upload import Upload

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
_DENIED = const(14)
_SEVERITY_ERROR = const(3)  # MAV_SEVERITY (a constant here: a lean board loads no statustext)

_TYPE_MISSION = const(0)
_TYPE_ALL = const(255)
_STATE_NO_MISSION = const(1)  # MISSION_STATE, without a runner
_STATE_NOT_STARTED = const(2)

_CAP_MISSION_FLOAT = const(1)
_CAP_MISSION_INT = const(4)
_CAP_MISSION_FENCE = const(16384)
_CAP_MISSION_RALLY = const(32768)

_CURRENT_PERIOD_MS = const(1000)
_IDLE_MS = const(1000)  # the tick with no transfer under way
# The requests about one plan, by msgid - 37: bits 0-2 the offset of target_system
# (mission_type is 2 bytes on), and how the request bears on the plan (transfer.CHANGE,
# EVERY: MISSION_CLEAR_ALL, in rare.py, says so itself).
_OPEN = (b"\x04"  # 37 MISSION_REQUEST_PARTIAL_LIST
         b"\x0c"  # 38 MISSION_WRITE_PARTIAL_LIST: 4 | CHANGE
         b"\x00\x00\x00\x00"  # 39-42: not requests about a plan
         b"\x00"  # 43 MISSION_REQUEST_LIST
         b"\x0a")  # 44 MISSION_COUNT: 2 | CHANGE
_NAMES = ("mission", "fence", "rally")  # also their files' names in storage


class Missions:
    NAME = "missions"
    CLOCK = False  # tells no time: a board with missions alone makes no ep.clock
    # Set on the instance where there is one (at start-up: no dict growth later).
    extra = None  # {command: need} the application added to the mission rules (allow)
    runner = None  # runner.MissionRunner
    rare = None  # rare.py, once loaded (see _on_rare)
    on_guided = None  # the application's guided go-to (docs/services/missions.md)

    def __init__(self, ep):
        # Few attributes: on a small heap a bigger instance dict may not find room. The
        # transfer first: its dict is the biggest made here, before opening the stores'
        # files leaves gaps in the heap.
        board = getattr(ep, "board", None)
        self.transfer = Upload(self, ep.setting("MISSION_WINDOW", 8), ep.setting("MISSION_RETRY_MS", 250),
                               ep.setting("MISSION_RTO_MIN_MS", 20), ep.setting("MISSION_RTO_MAX_MS", 1000),
                               ep.setting("MISSION_RETRIES", 5))
        capacities = (ep.setting("MISSION_CAPACITY", 500), ep.setting("FENCE_CAPACITY", 100),
                      ep.setting("RALLY_CAPACITY", 20))
        self.stores = [None, None, None]
        for t in range(3):
            if capacities[t] or t == 0:
                self.stores[t] = MissionStore(ep.storage, _NAMES[t], t, capacities[t])
        self.frames = getattr(board, "MISSION_FRAMES", (0, 2, 3, 5, 6))
        self.timeout_ms = ep.setting("MISSION_TIMEOUT_MS", 5000)
        self.jump_slots = ep.setting("MISSION_JUMP_SLOTS", 16)
        for command in getattr(board, "MISSION_COMMANDS", ()):
            self.allow(command)
        self.rec = bytearray(RECORD_SIZE)  # the record of the item in hand
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
        t = self.transfer
        for s in stores:
            if s is not None and s.corrupt:
                ep.statustext(_SEVERITY_ERROR, "Stored %s plan corrupt: cleared" % _NAMES[s.mission_type])
        # MISSION_ITEM_INT and MISSION_REQUEST_INT are in today's dialect, not the seed's
        # (where id 51 is another message); mission_type is an extension field.
        self.has_int = ep.has(_MSG_ITEM_INT) and ep.fmt(_MSG_ITEM_INT).startswith("<ffffiif") \
            and ep.has(_MSG_REQUEST_INT) and ep.fmt(_MSG_REQUEST_INT).startswith("<HBB")
        self.has_type = (ep.dialect.CRC_LEN.get(_MSG_COUNT, 0) >> 16) >= 5
        item = self._on_item  # (a bound method is an object: one each, shared by two ids)
        request = t.on_request
        rare = self._on_rare
        for msgid, handler in ((_MSG_COUNT, self._on_count), (_MSG_WRITE_PARTIAL_LIST, rare),
                               (_MSG_REQUEST_LIST, t.on_request_list), (_MSG_REQUEST_PARTIAL_LIST, rare),
                               (_MSG_CLEAR_ALL, rare), (_MSG_SET_CURRENT, rare), (_MSG_ACK, t.on_ack)):
            ep.on(msgid, handler)
        # Items and requests, a hundred a transfer, leave the tick no work (its retry and
        # staleness deadlines stand; an item that leaves requests unasked wakes it):
        # their passes run no tick at all.
        ep.on(_MSG_ITEM, item, False)
        ep.on(_MSG_REQUEST, request, False)
        ep.capabilities |= _CAP_MISSION_FLOAT
        if self.has_int:
            ep.on(_MSG_ITEM_INT, item, False)
            ep.on(_MSG_REQUEST_INT, request, False)
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
        t = self.transfer
        ms = _IDLE_MS  # to the next retry (an upload), 1 while pushing
        if t.state != IDLE and ticks_diff(now, t.progress) >= self.timeout_ms:
            t.cancel()  # stale: the ground station went away, or only starts over
        elif t.state == UPLOAD:
            ms = t.tick(now)
            t.look = ticks_add(now, ms)
        elif t.state == PUSH:
            self.rare.push(t, now)
            ms = 1
        self._current(now)
        if t.state != IDLE:  # the retry, or the transfer gone stale
            stale = self.timeout_ms - ticks_diff(now, t.progress) + 1
            return ms if ms < stale else stale
        return ticks_diff(self._current_due, now) if self.ep.services.get("streams") is None else to_grid(now, _IDLE_MS)

    def _current(self, now):
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
        """Send MISSION_CURRENT on the next pass (the runner calls this)."""
        self._current_changed = True
        self.ep.wake()

    # --- admission ----------------------------------------------------------------
    # mission_type is an extension field: where the dialect has none it reads as 0 (the
    # payload view holds stale bytes past a message's length), hence `if self.has_type`.

    def store_for(self, link, p):
        """Checks shared by the requests about one plan (_OPEN says where their fields
        are and how they bear on it) -> its MissionStore, or None once refused."""
        how = _OPEN[link.rx.msgid - _MSG_REQUEST_PARTIAL_LIST]
        at = how & 7
        if not self.ep.for_us(p[at], p[at + 1]):
            return None
        how = self.admit(link, p[at + 2] if self.has_type else 0, how)  # -> the plan type
        return self.stores[how] if how >= 0 else None

    def admit(self, link, mt, how):
        """A request of plan type mt (how: its CHANGE, EVERY bits) may start -> mt, or -1
        once refused (its sender told)."""
        result = _DENIED
        if how & CHANGE and not self.ep.allows(link):
            pass
        elif not self.transfer.may_start(link, how):
            pass  # one transfer at a time: the one under way goes on
        elif (mt == _TYPE_MISSION or (mt == _TYPE_ALL and how & EVERY)
              or (mt < 3 and link.version == 2 and self.has_type and self.stores[mt] is not None)):
            self.transfer.end_for(link, how)
            return mt
        else:
            result = _UNSUPPORTED  # fence and rally need MAVLink 2
        self.reply(link, result, mt)
        return -1

    # --- upload (upload.py) ---------------------------------------------------------
    def _on_count(self, link, p):
        count = u16(p, 0)
        if self.transfer.late_count(link, p, count):
            return  # a late copy of the MISSION_COUNT that started this upload
        store = self.store_for(link, p)
        if store is None:
            return
        if count > store.capacity:
            self.reply(link, _NO_SPACE, store.mission_type)
        elif count == 0:
            self.reply(link, self.clear(store), store.mission_type)
        else:
            self.transfer.count = count
            self.transfer.end = count - 1
            self.transfer.upload(link, store, 0, 0)

    def _on_item(self, link, p):
        # MISSION_ITEM_INT and the seed's MISSION_ITEM share their layout but for x and y.
        if not self.ep.for_us(p[32], p[33]):
            return
        if p[35] >= 2 and self.on_guided is not None:
            self._guided(link, p)
        elif not self.transfer.holds(link, UPLOAD):
            self._on_rare(link, p)  # a repeat of the last item whose ACK was lost?
        elif (p[37] if self.has_type else 0) == self.transfer.store.mission_type:
            self.transfer.item(link, p, p[28] | p[29] << 8)  # seq

    def _guided(self, link, p):
        # current 2 / 3: not a plan's item but ArduPilot's "guided" go-to / change altitude
        # (MAVProxy's `guided`): the application's, answered with its result.
        result = self.on_guided(link, p, link.rx.msgid == _MSG_ITEM_INT)
        self.reply(link, result, 0)

    def commit(self, store, count):
        """Make the plan staged in store (count items) the plan in force -> MAV_MISSION_RESULT."""
        if not store.seal(count):
            return self.unsaved()
        if store.mission_type == _TYPE_MISSION and store.staged_jumps > self.jump_slots:
            return _NO_SPACE  # more DO_JUMPs than the runner keeps counters for
        return _ACCEPTED if store.commit() else self.unsaved()

    def unsaved(self):
        """Storage refused a new plan: said in a STATUSTEXT -> MAV_MISSION_ERROR."""
        self.ep.statustext(_SEVERITY_ERROR, b"Mission not saved: storage refused it")
        return _ERROR

    def clear(self, store):
        """Empty store's plan -> MAV_MISSION_RESULT."""
        if not store.begin(0):
            return self.unsaved()
        result = self.commit(store, 0)
        if result == _ACCEPTED:
            self.plan_changed(store, 0)
        return result

    def plan_changed(self, store, current):
        """A new plan is in store (current: the item to make current, -2 keep it)."""
        if store.mission_type == _TYPE_MISSION and self.runner is not None:
            self.runner.plan_changed(current)
        self.current_changed()

    # --- what a ground station seldom sends ------------------------------------------
    def _on_rare(self, link, p):
        # Partial lists, MISSION_CLEAR_ALL, MISSION_SET_CURRENT, items outside an upload:
        # rare.py, loaded on first use to keep it out of a small board's heap until then
        # (at start-up where the heap gets locked).
        if self.rare is None:
            from . import rare as mission_rare

            self.rare = mission_rare
        self.rare.on(self, link, p)

    # --- current item -------------------------------------------------------------
    def send_current(self, link):
        off = link.begin()
        buf = link.txbuf
        count = self.stores[0].count
        seq = 0
        if self.runner is not None:
            seq = self.runner.current
            buf[off + 4] = self.runner.state
            buf[off + 5] = self.runner.mode
        else:
            buf[off + 4] = _STATE_NOT_STARTED if count else _STATE_NO_MISSION
            buf[off + 5] = 0  # unknown: nothing here flies missions
        buf[off] = seq & 0xFF
        buf[off + 1] = seq >> 8
        count = count or 0xFFFF  # UINT16_MAX: no mission
        buf[off + 2] = count & 0xFF
        buf[off + 3] = count >> 8
        # mission_id, fence_id, rally_points_id, where the dialect has them
        self._put_id(buf, off + 6, 0)
        self._put_id(buf, off + 10, 1)
        self._put_id(buf, off + 14, 2)
        return link.send(_MSG_CURRENT)

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

    def reply(self, link, result, mt):
        """MISSION_ACK to the sender of the frame in hand."""
        self.ack(link, link.rx.sysid << 8 | link.rx.compid, result, mt)

    def ack(self, link, peer, result, mt):
        """MISSION_ACK of result to peer (sysid << 8 | compid) on link."""
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
    missions = ep.add(Missions(ep))
    if ep.setting("MISSION_RUNNER", True):  # (imported only then: a board may fly nothing)
        from .runner import MissionRunner

        MissionRunner(missions)
    if ep.setting("HEAP_LOCK", False):  # no loading on first use once the heap is locked
        from . import rare as mission_rare

        missions.rare = mission_rare
    return missions
