"""Mission execution support: which item the application flies now, and what comes next.
The application asks the runner for the current item, does what it says and calls
reached() when it is done; the runner tells the ground stations (MISSION_ITEM_REACHED,
MISSION_CURRENT), honours autocontinue, and steps over DO_JUMPs itself with the seed's
semantics (jump to param1, param2 times, -1 for ever, then fall through), its counters
in a fixed table of MISSION_JUMP_SLOTS. Every other command is the application's, handed
to it as it becomes current (on_item, runner.item). Stepping and runner.item allocate
nothing, on a 32-bit board too: an Item's coordinates are there as 16-bit halves, and
its floats are made when first asked for. Reference: docs/services/missions.md.
"""
import struct

from ...compat import const, ticks_diff
from ...fields import LOCAL_FRAMES, f32_to_small, i16, u16
from ...kernels import copy
from .store import RECORD_SIZE

NO_MISSION = const(1)  # MISSION_STATE
NOT_STARTED = const(2)
ACTIVE = const(3)
PAUSED = const(4)
COMPLETE = const(5)

_CMD_DO_JUMP = const(177)
_CMD_DO_SET_MISSION_CURRENT = const(224)
_CMD_MISSION_START = const(300)
_RESULT_ACCEPTED = const(0)
_RESULT_DENIED = const(2)
_RESULT_FAILED = const(4)
_NAN = float("nan")


class Item:
    """One mission item, decoded from its record (what it offers without allocating, and
    what it makes on first use: docs/services/missions.md)."""

    def __init__(self):
        self.rec = bytearray(RECORD_SIZE)
        self._f = None  # (param1..4, x, y, z, lat, lon) once asked for
        self.decode(0, self.rec)

    def decode(self, seq, rec):
        if rec is not self.rec:
            copy(self.rec, rec, 0, RECORD_SIZE)
        rec = self.rec
        self.seq = seq
        c = rec[28] | rec[29] << 8
        self.command = c
        self.frame = rec[30]
        self.autocontinue = rec[31]
        self.is_nav = c < 100 or 5000 <= c < 5200  # MAV_CMD_NAV_* ids
        self.is_condition = 100 <= c < 160
        self.is_do = 160 <= c < 250
        self.x_hi = i16(rec, 18)
        self.x_lo = u16(rec, 16)
        self.y_hi = i16(rec, 22)
        self.y_lo = u16(rec, 20)
        # x, y unset (INT32_MAX: "where the vehicle is", as a takeoff may say)
        self.x_unset = self.x_hi == 0x7FFF and self.x_lo == 0xFFFF
        self.y_unset = self.y_hi == 0x7FFF and self.y_lo == 0xFFFF
        self._f = None
        return self

    def _floats(self):
        f = self._f
        if f is None:
            f = struct.unpack_from("<ffffiif", self.rec, 0)
            scale = 1e4 if self.frame in LOCAL_FRAMES else 1e7
            f = self._f = f + (_NAN if self.x_unset else f[4] / scale, _NAN if self.y_unset else f[5] / scale)
        return f

    @property
    def param1(self):
        return self._floats()[0]

    @property
    def param2(self):
        return self._floats()[1]

    @property
    def param3(self):
        return self._floats()[2]

    @property
    def param4(self):
        return self._floats()[3]

    @property
    def x(self):
        return self._floats()[4]

    @property
    def y(self):
        return self._floats()[5]

    @property
    def z(self):
        return self._floats()[6]

    @property
    def lat(self):
        return self._floats()[7]

    @property
    def lon(self):
        return self._floats()[8]


class MissionRunner:
    def __init__(self, missions):
        self.missions = missions
        missions.runner = self
        jump_slots = missions.jump_slots
        self.store = missions.stores[0]
        self.current = 0
        self.last = -1  # the last item to run (MISSION_START param2), -1: to the end
        self.state = NOT_STARTED if self.store.count else NO_MISSION
        self.waiting = False
        self.running = False  # in the mode that flies the mission (run() / pause())
        self.started_ms = missions.ep.now  # when the current item became current
        self.on_item = None
        self._item = Item()
        self._decoded = False  # _item holds the current item
        self._auto = 1  # its autocontinue
        self._rec = bytearray(RECORD_SIZE)
        self._jump_seq = [-1] * jump_slots
        self._jump_done = [0] * jump_slots
        self._load(0)
        ep = missions.ep
        ep.commands[_CMD_DO_SET_MISSION_CURRENT] = self._cmd_set_current
        ep.commands[_CMD_MISSION_START] = self._cmd_start

    @property
    def item(self):
        """The current item (None without a plan): one Item, decoded again when the
        current item changes (allocation-free; its floats are made when asked for)."""
        if not self._decoded:
            item = self._item
            if not self.store.read(self.current, item.rec):
                return None
            item.decode(self.current, item.rec)
            self._decoded = True
        return self._item

    @property
    def mode(self):
        """MISSION_CURRENT.mission_mode: 1 in the mission's mode, 2 suspended, 0 unknown."""
        status = self.missions.ep.services.get("status")
        if status is not None and status.flight_mode is not None:
            return 1 if status.flight_mode == "AUTO" else 2  # RTL, LAND ... are AUTO too
        if status is not None:
            return 1 if status.auto else 2
        return 1 if self.running else 2

    def elapsed_ms(self, now=None):
        """Time since the current item became current (CONDITION_DELAY, LOITER_TIME)."""
        return ticks_diff(self.missions.ep.now if now is None else now, self.started_ms)

    def read(self, seq, item=None):
        """Any item of the plan, decoded (a new Item unless one is given); None if absent."""
        if item is None:
            item = Item()
        if not self.store.read(seq, item.rec):  # straight into the item: nothing to copy
            return None
        return item.decode(seq, item.rec)

    def next_nav(self, after=-1, item=None):
        """The first NAV item after `after` (default: the current item), or None; into
        `item` if given (no allocation), else into a new Item."""
        seq = (self.current if after < 0 else after) + 1
        if item is None:
            item = Item()
        while seq < self.store.count:
            if self.read(seq, item) is not None and item.is_nav:
                return item
            seq += 1
        return None

    # --- changes from the ground or the application --------------------------------
    def plan_changed(self, current=0):
        """A new plan is in force; current -1 keeps the current item if it still exists."""
        self._reset_jumps()
        self.last = -1
        self.waiting = False
        count = self.store.count
        if current < 0:
            current = self.current
        if current >= count:
            current = 0
        if count == 0:
            self.state = NO_MISSION
            self._load(0)
        elif self.state == ACTIVE:
            self._settle(current)
        else:
            self.state = NOT_STARTED
            self._load(current)
        self.missions.current_changed()

    def start(self, first=0, last=-1):
        """Run the plan from `first`; stop after `last` (-1, 0 or out of range: the end)."""
        count = self.store.count
        if count == 0 or first < 0 or first >= count:
            return False
        self.last = last if first <= last < count and last > 0 else -1
        self._reset_jumps()
        self.waiting = False
        self.running = True
        self.state = ACTIVE
        self._settle(first)
        return True

    def run(self):
        """The vehicle entered the mode that flies the mission: go on from the current item."""
        self.running = True
        if self.state == NOT_STARTED or self.state == PAUSED:
            self.state = ACTIVE
            self._settle(self.current)
        return self.state == ACTIVE

    def pause(self):
        """The vehicle left that mode; run() resumes at the current item."""
        self.running = False
        if self.state == ACTIVE:
            self.state = PAUSED
            self.missions.current_changed()

    def set_current(self, seq, reset=False):
        if seq < 0 or seq >= self.store.count:
            return False
        if reset:
            self._reset_jumps()
        self.waiting = False
        if self.state == COMPLETE:
            self.state = ACTIVE if self.running else PAUSED
        if self.state == ACTIVE:
            self._settle(seq)
        else:
            self._load(seq)
            self.missions.current_changed()
        return True

    def reached(self):
        """The application is done with the current item -> False if not running a mission."""
        if self.state != ACTIVE or self.current >= self.store.count or self.waiting:
            return False
        self.missions.send_reached(self.current)
        if self._auto:
            self._advance()
        else:
            self.waiting = True
        return True

    def proceed(self):
        """Go on after an item without autocontinue."""
        if self.waiting:
            self.waiting = False
            self._advance()

    def _cmd_set_current(self, cmd):
        # param1: the item (-1: unchanged), param2: 1 resets the jump counters.
        if not self.missions.ep.allows(cmd.link):
            return _RESULT_DENIED
        seq = -1 if cmd.nan(1) else cmd.int(1)
        reset = not cmd.nan(2) and cmd.int(2) == 1
        if seq < 0:
            if not reset:
                return _RESULT_ACCEPTED
            seq = self.current
        return _RESULT_ACCEPTED if self.set_current(seq, reset) else _RESULT_FAILED

    def _cmd_start(self, cmd):
        # param1: first item, param2: last item (0 as QGroundControl sends it: to the end).
        if not self.missions.ep.allows(cmd.link):
            return _RESULT_DENIED
        first = 0 if cmd.nan(1) else cmd.int(1)
        last = -1 if cmd.nan(2) else cmd.int(2)
        return _RESULT_ACCEPTED if self.start(first, last) else _RESULT_FAILED

    # --- stepping -------------------------------------------------------------------
    def _advance(self):
        if self.current == self.last:
            self._complete()
        else:
            self._settle(self.current + 1)

    def _settle(self, seq):
        """Make seq current, taking DO_JUMPs on the way."""
        steps = 2 * self.store.count + 2  # jump chains without a real item in between end here
        rec = self._rec
        while steps:
            steps -= 1
            if seq >= self.store.count or not self.store.read(seq, rec):
                self._complete()
                return
            if rec[28] | rec[29] << 8 != _CMD_DO_JUMP:
                self._load(seq)
                self.missions.current_changed()
                return
            target = f32_to_small(rec, 0)
            repeat = f32_to_small(rec, 4)
            slot = self._jump_slot(seq)
            if slot >= 0 and (repeat < 0 or self._jump_done[slot] < repeat):
                if self._jump_done[slot] < 0xFFFF:
                    self._jump_done[slot] += 1
                seq = target
            else:
                seq += 1
        self.missions.ep.statustext(3, b"Mission: DO_JUMP loop without items")
        self._complete()

    def _complete(self):
        self.state = COMPLETE
        self.waiting = False
        self.missions.current_changed()

    def _load(self, seq):
        self.current = seq
        self.started_ms = self.missions.ep.now
        self._decoded = False
        self._auto = self._rec[31] if self.store.read(seq, self._rec) else 1
        if self.on_item is not None:
            self.on_item(self)

    def _jump_slot(self, seq):
        seqs = self._jump_seq
        for i in range(len(seqs)):
            if seqs[i] == seq:
                return i
            if seqs[i] < 0:
                seqs[i] = seq
                self._jump_done[i] = 0
                return i
        return -1  # more DO_JUMPs than slots: uploads with that many are refused

    def _reset_jumps(self):
        for i in range(len(self._jump_seq)):
            self._jump_seq[i] = -1
            self._jump_done[i] = 0
