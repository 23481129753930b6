"""Vehicle status: identity and state (HEARTBEAT), health (SYS_STATUS), clock
(SYSTEM_TIME), PING, STATUSTEXT, AUTOPILOT_VERSION, HOME_POSITION, ground-station
presence per link and operator control.

It also holds the vehicle state other services and the application share:

    status = ep.services["status"]
    status.armed, status.base_mode, status.custom_mode, status.system_status, status.auto
    status.flight_mode   the current mode's name in the board's FLIGHT_MODES ("GUIDED"; None
                         on a board without a table)
    status.arm(True, force=False) -> MAV_RESULT   (status.reason says why it was refused)
    status.set_mode(base_mode, custom_mode) -> MAV_RESULT   a ground station's request
    status.set_flight_mode("RTL") -> MAV_RESULT   the application's own change (no veto)
    status.set_airborne(True | False)   HEARTBEAT system_status: ACTIVE in the air, STANDBY
                         on the ground; until first called, ACTIVE while armed
    status.set_state(MAV_STATE_CRITICAL) / set_state(0)  (back to the life cycle)
    status.set_home(lat_e7, lon_e7, alt_mm), status.home_set, status.home
    status.set_sensors(present, enabled, health), status.set_battery(mv, ca, percent)
    status.fence_enabled, status.fence_breached   set by an application that checks a fence
    status.custom_modes   the board's FLIGHT_MODES (modes.py: the rows, numbering per link)
    status.set_clock(unix_usec), status.statustext(severity, text), status.gcs_present(link)
    status.reboot(1) (2: shutdown, if the board has shutdown()): Reboot is raised out of
    a poll reboot_delay_ms later, once the ACK and a STATUSTEXT are on the wire
Hooks the application may set (None: no opinion):
    arm_check(arm) -> None | reason | (MAV_RESULT, reason)   veto arming or disarming
    mode_check(base_mode, custom_mode) -> same                 veto a mode
    flight_mode_check(name) -> same                            veto a mode by its name
    position() -> (lat_e7, lon_e7, alt_mm) or None              for DO_SET_HOME "current"
    on_gcs_lost(link), on_gcs_regained(link)                   fail-safe triggers
    on_hil(enabled)          HIL_ENABLED turned on or off (status.hil): actuators blocked
A command forced with 21196 (COMPONENT_ARM_DISARM param2) skips arm_check.

Modes: a board with a mode table (FLIGHT_MODES; services/modes.py says how requests
find a row and how each link numbers it) is always in one of its modes, the row numbered
0 from boot; a mode sets its own MAV_MODE_FLAG bits. A board without one takes
MAV_MODE_FLAG bits of mode_flags_supported (the board's MODE_FLAGS) with custom_mode 0.
Anything else is refused (DENIED, with a STATUSTEXT) and the mode stays as it was.

SYS_STATUS: the application's sensor bits (set_sensors), and two the status service
fills itself. MAV_SYS_STATUS_PREARM_CHECK is always present and enabled, healthy when
arming would be accepted: armed already, or arm_check(True) has no objection (asked
once a second while disarmed: keep it free of side effects). MAV_SYS_STATUS_GEOFENCE
is present and enabled while the application checks a fence (fence_enabled) and a fence
plan is stored; healthy unless fence_breached (ground stations read a clear health bit
as a breach, fence or none).

Load (SYS_STATUS.load) is the share of wall time not spent in status.idle(ms), which
main.py's loop sleeps through; an application running its own loop calls idle(ms),
or add_idle(us) for time it waited elsewhere. drop_rate_comm and errors_comm come from
the links' parsers: sequence gaps against frames received (smoothed over ~10 s), and
frames that failed their CRC or were malformed (a running total). errors_count1 is
the number of STATUSTEXTs dropped because the queue was full.
"""
from struct import pack_into

from ... import VERSION
from ...compat import const, ticks_ms, ticks_us, ticks_diff, ticks_add, sleep_ms
from ...endpoint import REBOOT, SHUTDOWN
from ...fields import u32
from ...kernels import copy
from ...link import RANK_VITAL, RANK_OTHER, RANK_AUTO
from ...parser import COUNT_WRAP
from ...statustext import TextQueue, CRITICAL, NOTICE, WARNING
from .operator import Operator, on_change_operator_control
from . import vehicle_commands
from .modes import Modes

USES = ("missions", "streams", "signing")  # the fence plan; who sends SYS_STATUS; signing commands


# MAV_STATE
MAV_STATE_BOOT = const(1)
MAV_STATE_STANDBY = const(3)
MAV_STATE_ACTIVE = const(4)
MAV_STATE_CRITICAL = const(5)
MAV_STATE_EMERGENCY = const(6)
# MAV_MODE_FLAG
MODE_ARMED = const(128)
MODE_MANUAL_INPUT = const(64)
MODE_HIL = const(32)
MODE_STABILIZE = const(16)
MODE_GUIDED = const(8)
MODE_AUTO = const(4)
MODE_TEST = const(2)
MODE_CUSTOM = const(1)

_ACCEPTED = const(0)
_DENIED = const(2)

# MAV_SYS_STATUS bits the status service fills: both below 2^30 (small ints on a 32-bit
# board), merged into the application's words as bytes, so its masks may use bit 31.
_PREARM_CHECK = const(0x10000000)  # byte 3, 0x10
_GEOFENCE = const(0x100000)  # byte 2, 0x10
_OWN_BIT = const(0x10)  # the bit each of them is in its byte
_FENCE_PLAN = const(1)  # missions.stores[1]: the fence

_MSG_HEARTBEAT = const(0)
_MSG_SYS_STATUS = const(1)
_MSG_SYSTEM_TIME = const(2)
_MSG_PING = const(4)
_MSG_CHANGE_OPERATOR_CONTROL = const(5)
_MSG_SET_MODE = const(11)
_MSG_AUTOPILOT_VERSION = const(148)
_MSG_HOME_POSITION = const(242)
_MSG_CURRENT_MODE = const(436)
_MAV_TYPE_GCS = const(6)
_CAP_MAVLINK2 = const(8192)
_MAVLINK_VERSION = const(3)
_FIRMWARE_VERSION_TYPE_DEV = const(0)

# Layouts packed here; fields a dialect adds after them are zeroed first.
_SYS_STATUS_FMT = "<IIIHHhHHHHHHb"
_AUTOPILOT_VERSION_FMT = "<QQIIIIHH"
_HOME_POSITION_FMT = "<iiifff4f"

_PERIOD_MS = const(1000)  # HEARTBEAT, and SYS_STATUS when no streams service schedules it
_TEXT_FRAME = const(66)  # bytes of a MAVLink 2 STATUSTEXT, for pacing on slow links
_TEXT_SHARE = const(4)  # STATUSTEXT may use a quarter of the slowest link
_GCS_NEVER = const(0)  # no GCS heartbeat yet on this link (the tables start zeroed)
_GCS_PRESENT = const(1)
_GCS_LOST = const(2)
_RESET = const(0x10000000)  # half of the counters' modulus (parser.COUNT_WRAP + 1)


class Status:
    NAME = "status"

    def __init__(self, mav_type=2, autopilot=0, gcs_timeout_ms=5000, passkey=None, uid=0,
                 reboot_delay_ms=100, text_slots=8):
        self.mav_type = mav_type
        self.autopilot = autopilot
        self.gcs_timeout_ms = gcs_timeout_ms
        self.passkey = passkey
        self.uid = uid
        self.reboot_delay_ms = reboot_delay_ms
        self.armed = False
        self.mode = 0  # MAV_MODE_FLAG bits but SAFETY_ARMED
        self.base_mode = 0
        self.custom_mode = 0
        self.system_status = MAV_STATE_BOOT
        self.mode_flags_supported = MODE_MANUAL_INPUT | MODE_STABILIZE | MODE_GUIDED | MODE_AUTO | MODE_CUSTOM
        self.modes = Modes(())
        self.mode_row = -1  # the current mode's row in the table, -1: none (flag-only modes)
        self.intended_row = -1  # the last one a ground station asked for
        self.flight_mode = None
        self.flight_mode_check = None
        self._mode_changed = False
        self._airborne = -1  # set_airborne: 1 in the air, 0 on the ground, -1 not told
        self.hil = False  # MAV_MODE_FLAG_HIL_ENABLED, on a board whose MODE_FLAGS allow it
        self.on_hil = None
        self._override = 0  # a MAV_STATE the application set, 0: follow the life cycle
        self._initialised = False
        self.reason = None
        self.arm_check = None
        self.mode_check = None
        self.position = None
        self.on_gcs_lost = None
        self.on_gcs_regained = None
        # SYS_STATUS figures
        self.sensors_present = 0
        self.sensors_enabled = 0
        self.sensors_health = 0
        self.fence_enabled = False
        self.fence_breached = False
        self._own_present = _PREARM_CHECK  # the bits above, as of the last _own_bits()
        self._own_health = _PREARM_CHECK | _GEOFENCE
        self.voltage_mv = 0xFFFF  # UINT16_MAX: not measured
        self.current_ca = -1
        self.battery_remaining = -1
        self.load = 0
        self.drop_rate_comm = 0
        self.errors_comm = 0
        # Home
        self.home_set = False
        self.home_lat = 0
        self.home_lon = 0
        self.home_alt = 0
        self._home_changed = False
        self._one = 1.0  # quaternion w, made once
        # Clock
        self._clock_from_app = False  # the time of day came from the application (ep.clock)
        # Load and link figures, per window
        self._win_us = ticks_us()
        self._idle_us = 0
        self._idle_seen = False
        self._frames = 0
        self._lost = 0
        self._acc_frames = 0
        self._acc_lost = 0
        self._next_period = 0
        self._next_text = 0
        self._text_gap_ms = 0
        self._reboot = 0  # 1 reboot, 2 shutdown once _reboot_at is reached
        self._reboot_at = 0
        self.texts = TextQueue(text_slots)
        self.operator = None
        self._gcs_seen = []
        self._gcs_state = bytearray(0)

    # --- wiring ---------------------------------------------------------------
    def attach(self, ep):
        self.ep = ep
        now = ep.now
        self._next_period = now
        self._next_text = now
        self._links_changed()
        ep.capabilities |= _CAP_MAVLINK2
        self._sw_version = _version_word(VERSION, _FIRMWARE_VERSION_TYPE_DEV)
        self._os_version = _os_version()
        ep.on(_MSG_HEARTBEAT, self._on_heartbeat)
        self.modes.attach(ep, self)
        ep.on(_MSG_PING, self._on_ping)
        ep.on(_MSG_SYSTEM_TIME, self._on_system_time)
        ep.on(_MSG_SET_MODE, self._on_set_mode)
        ep.on(_MSG_CHANGE_OPERATOR_CONTROL, self._on_operator_control)
        ep.producers[_MSG_HEARTBEAT] = self.send_heartbeat
        ep.producers[_MSG_SYS_STATUS] = self.send_sys_status
        ep.producers[_MSG_SYSTEM_TIME] = self.send_system_time
        if ep.has(_MSG_AUTOPILOT_VERSION) and ep.fmt(_MSG_AUTOPILOT_VERSION).startswith(_AUTOPILOT_VERSION_FMT):
            ep.producers[_MSG_AUTOPILOT_VERSION] = self.send_autopilot_version
        if ep.has(_MSG_HOME_POSITION) and ep.fmt(_MSG_HOME_POSITION).startswith(_HOME_POSITION_FMT):
            ep.producers[_MSG_HOME_POSITION] = self.send_home_position
        if self.passkey:
            self.operator = Operator(ep, self.passkey, self.gcs_timeout_ms)
            ep.operator = self.operator
        vehicle_commands.install(ep, self)
        # Announce BOOT at once: a ground station already listening sees the vehicle come up.
        for link in ep.links:
            self.send_heartbeat(link)

    def _links_changed(self):
        # Rare (start-up): size the per-link tables and the STATUSTEXT pacing.
        links = self.ep.links
        self.modes.links_changed(links)
        while len(self._gcs_seen) < len(links):
            self._gcs_seen.append(0)
            self._gcs_state = self._gcs_state + b"\0"
        slowest = 0
        for link in links:
            if slowest == 0 or link.bytes_per_s < slowest:
                slowest = link.bytes_per_s
        self._text_gap_ms = _TEXT_FRAME * 1000 * _TEXT_SHARE // slowest if slowest else 0

    # --- state ----------------------------------------------------------------
    @property
    def custom_modes(self):
        return self.modes.table

    @custom_modes.setter
    def custom_modes(self, table):
        self.modes.set_table(table)

    @property
    def auto(self):
        return bool(self.mode & MODE_AUTO)

    @property
    def home(self):
        return (self.home_lat, self.home_lon, self.home_alt) if self.home_set else None

    def _update(self):
        self.base_mode = self.mode | (MODE_ARMED if self.armed else 0) | (MODE_HIL if self.hil else 0)
        if self._override:
            self.system_status = self._override
        elif not self._initialised:
            self.system_status = MAV_STATE_BOOT
        elif self._airborne >= 0:
            self.system_status = MAV_STATE_ACTIVE if self._airborne else MAV_STATE_STANDBY
        else:
            self.system_status = MAV_STATE_ACTIVE if self.armed else MAV_STATE_STANDBY

    def set_airborne(self, airborne):
        """In the air (True) or on the ground: HEARTBEAT's ACTIVE or STANDBY from now on."""
        self._airborne = 1 if airborne else 0
        self._update()

    def set_state(self, state):
        """Report a MAV_STATE (e.g. CRITICAL, EMERGENCY) until set_state(0)."""
        self._override = state
        self._update()

    def arm(self, arm, force=False):
        """Arm (True) or disarm -> MAV_RESULT; on refusal self.reason says why."""
        self.reason = None
        arm = bool(arm)
        if arm == self.armed:
            return _ACCEPTED
        if not force and self.arm_check is not None:
            result = self._veto(self.arm_check(arm), b"Arm: " if arm else b"Disarm: ")
            if result != _ACCEPTED:
                return result
        self.armed = arm
        self._update()
        return _ACCEPTED

    def set_mode(self, base_mode, custom_mode=0):
        """A ground station's mode request (SAFETY_ARMED is ignored: arming is its own
        command) -> MAV_RESULT. HIL_ENABLED, where the board's MODE_FLAGS allow it,
        goes with any mode: the request's bit turns it on or off."""
        self.reason = None
        if base_mode & MODE_HIL and not self.mode_flags_supported & MODE_HIL:
            self.reason = "HIL not supported"
            self.statustext(WARNING, b"Mode: HIL not supported")
            return _DENIED
        result = self._set_mode(base_mode & 0x5F, custom_mode)
        if result == _ACCEPTED:
            self._set_hil(base_mode & MODE_HIL)
        return result

    def _set_hil(self, on):
        on = bool(on)
        if on != self.hil:
            self.hil = on
            self._update()
            if self.on_hil is not None:
                self.on_hil(on)  # the application blocks (or frees) its actuators

    def _set_mode(self, base_mode, custom_mode):
        row = self.modes.find(base_mode, custom_mode)
        if row >= 0:
            return self.enter(row, True)
        if row == -1 or custom_mode:
            self.reason = "no such mode"  # a constant: a board may lock its heap
            self.statustext(WARNING, b"Mode: no such mode")
            return _DENIED
        return self._flag_mode(base_mode & 0x5E)

    def _flag_mode(self, flags):
        # A board without a mode table: the flags alone.
        if flags & ~self.mode_flags_supported:
            self.reason = "mode flags 0x%02x not supported" % (flags & ~self.mode_flags_supported)
            self.statustext(WARNING, "Mode: " + self.reason)
            return _DENIED
        if self.mode_check is not None:
            result = self._veto(self.mode_check(flags, 0), b"Mode: ")
            if result != _ACCEPTED:
                return result
        self.mode = flags
        self.custom_mode = 0
        self._update()
        return _ACCEPTED

    def enter(self, row, asked):
        """Into mode `row` of the table: asked (by a ground station) goes through the
        vetoes, the application's own change (set_flight_mode) does not."""
        if asked:
            result = self._vet(row)
            if result != _ACCEPTED:
                return result
            self.intended_row = row
        self._apply(row)
        return _ACCEPTED

    # (Three small functions, not one: each frame stays within what MicroPython keeps
    # off the heap.)
    def _vet(self, row):
        entry = self.modes.table[row]
        flags = entry[2] & 0x7E | MODE_CUSTOM
        if flags & ~self.mode_flags_supported:
            self.reason = "mode flags not supported"
            self.statustext(WARNING, b"Mode: flags not supported")
            return _DENIED
        if self.mode_check is not None:
            answer = self.mode_check(flags, entry[0])
            if answer is not None:
                return self._veto(answer, b"Mode: ")
        if self.flight_mode_check is not None:
            answer = self.flight_mode_check(entry[1])
            if answer is not None:
                return self._veto(answer, b"Mode: ")
        return _ACCEPTED

    def _apply(self, row):
        entry = self.modes.table[row]
        if row != self.mode_row:
            self._mode_changed = True
        self.mode = entry[2] & 0x7E | MODE_CUSTOM
        self.custom_mode = entry[0]
        self.mode_row = row
        self.flight_mode = entry[1]
        self._update()

    def set_flight_mode(self, name):
        """The application changes mode (a failsafe, a takeoff done) -> MAV_RESULT."""
        row = self.modes.by_name(name)
        if row < 0:
            return _DENIED
        return self.enter(row, False)

    def _veto(self, answer, prefix):
        if answer is None:
            return _ACCEPTED
        if isinstance(answer, tuple):
            result, reason = answer
        else:
            result, reason = _DENIED, answer
        if result == _ACCEPTED:
            return _ACCEPTED
        self.reason = reason
        if reason:
            self.statustext(CRITICAL, prefix.decode() + reason)
        return result

    def set_home(self, lat_e7, lon_e7, alt_mm):
        self.home_lat = int(lat_e7)
        self.home_lon = int(lon_e7)
        self.home_alt = int(alt_mm)
        self.home_set = True
        self._home_changed = True  # ground stations learn it from HOME_POSITION

    def set_sensors(self, present, enabled, health):
        """MAV_SYS_STATUS_SENSOR bitmasks."""
        self.sensors_present = present
        self.sensors_enabled = enabled
        self.sensors_health = health

    def set_battery(self, voltage_mv, current_ca=-1, remaining=-1):
        self.voltage_mv = voltage_mv
        self.current_ca = current_ca
        self.battery_remaining = remaining

    def set_clock(self, unix_usec):
        """The time of day, from an RTC or GPS; until then SYSTEM_TIME says 0 (unknown).
        (An int: call it at start-up or rarely; ep.clock.set_unix takes bytes.)"""
        self.ep.clock.set_unix(unix_usec.to_bytes(8, "little"))
        self._clock_from_app = True

    def unix_usec(self):
        return self.ep.clock.unix_usec()

    @property
    def uptime_ms(self):
        return self.ep.clock.uptime_ms()

    def statustext(self, severity, text):
        self.texts.put(severity, text)

    def gcs_present(self, link):
        i = link.index
        return i < len(self._gcs_state) and self._gcs_state[i] == _GCS_PRESENT

    def reboot(self, action=1):
        """Reboot (1) or shut down (2) after reboot_delay_ms, so the ACK gets out first."""
        self._reboot = action
        self._reboot_at = ticks_add(self.ep.now, self.reboot_delay_ms)
        self.statustext(NOTICE, b"Rebooting" if action == 1 else b"Shutting down")

    def idle(self, ms):
        """Sleep ms, counted as idle time for SYS_STATUS.load."""
        t = ticks_us()
        sleep_ms(ms)
        self._idle_us += ticks_diff(ticks_us(), t)
        self._idle_seen = True

    def add_idle(self, us):
        self._idle_us += us
        self._idle_seen = True

    # --- periodic work --------------------------------------------------------
    # Small functions, few locals, links by index where a for loop's iterator (four
    # words) would tip it: MicroPython takes a frame state of more than about 11 words
    # from the heap on every call.
    def tick(self, now):
        if not self._initialised:
            self._initialised = True
            self.modes.wrap_request_message()
            self._update()
        if self._mode_changed:
            self._mode_changed = False
            self._mode_announce()
        if len(self._gcs_state) < len(self.ep.links):
            self._links_changed()
        if ticks_diff(now, self._next_period) >= 0:
            self._period(now)
        self._check_gcs(now)
        if self._home_changed:
            self._home_changed = False
            for link in self.ep.links:
                self.send_home_position(link)
        if self.texts.count and ticks_diff(now, self._next_text) >= 0:
            self._next_text = ticks_add(now, self._text_gap_ms)
            for link in self.ep.links:
                self.texts.send(link)
            self.texts.pop()
        if self._reboot and ticks_diff(now, self._reboot_at) >= 0:
            action = self._reboot
            self._reboot = 0
            if action == 2:
                self.ep.board.shutdown()
                raise SHUTDOWN
            raise REBOOT

    def _mode_announce(self):
        # CURRENT_MODE on a change, where the dialect has it (a rare event).
        send = self.ep.producers.get(_MSG_CURRENT_MODE)
        if send is not None:
            for link in self.ep.links:
                send(link)

    def _period(self, now):
        # Once a second: HEARTBEAT, and SYS_STATUS unless the streams service schedules it.
        self._next_period = ticks_add(self._next_period, _PERIOD_MS)
        if ticks_diff(now, self._next_period) >= 0:  # fell behind: keep the rate, not the backlog
            self._next_period = ticks_add(now, _PERIOD_MS)
        self._measure()
        self._own_bits()
        sys_status = "streams" not in self.ep.services
        for link in self.ep.links:
            link.rank = RANK_VITAL  # the 1 Hz HEARTBEAT goes whatever else the link carries
            self.send_heartbeat(link)
            link.rank = RANK_AUTO
            if sys_status:
                self.send_sys_status(link)

    def _measure(self):
        # Once a second: loop load and link figures for SYS_STATUS.
        t = ticks_us()
        wall = ticks_diff(t, self._win_us)
        if self._idle_seen and wall > 0:
            busy = (wall - self._idle_us) * 1000 // wall
            self.load = 0 if busy < 0 else 1000 if busy > 1000 else busy
        self._win_us = t
        self._idle_us = 0
        self._idle_seen = False
        self._link_figures()

    def _own_bits(self):
        # Once a second: what the arming check and the fence say, for SYS_STATUS.
        present = _PREARM_CHECK
        health = _PREARM_CHECK if self.armed or self._prearm_ok() else 0
        if self.fence_enabled and self._fence_plan():
            present |= _GEOFENCE
        if not self.fence_breached:
            health |= _GEOFENCE
        self._own_present = present
        self._own_health = health

    def _prearm_ok(self):
        if self.arm_check is None:
            return True
        try:
            answer = self.arm_check(True)
        except Exception:  # a broken check is no green light
            return False
        return answer is None or (isinstance(answer, tuple) and answer[0] == _ACCEPTED)

    def _fence_plan(self):
        missions = self.ep.services.get("missions")
        store = missions.stores[_FENCE_PLAN] if missions is not None else None
        return store is not None and store.count > 0

    def _link_figures(self):
        # The parser's counters wrap at 2^29 (parser.COUNT_WRAP): sums and differences
        # are taken modulo that, so that none reaches 2^30 (a heap object on a 32-bit board).
        frames = lost = errors = 0
        i = 0
        while i < len(self.ep.links):
            rx = self.ep.links[i].rx
            frames = (frames + rx.frames) & COUNT_WRAP
            lost = (lost + rx.lost) & COUNT_WRAP
            errors = _capped(_capped(errors + _capped(rx.crc_errors)) + _capped(rx.bad_frames))
            i += 1
        self._smooth((frames - self._frames) & COUNT_WRAP, (lost - self._lost) & COUNT_WRAP)
        self._frames = frames
        self._lost = lost
        self.errors_comm = errors

    def _smooth(self, df, dl):
        if df < _RESET and dl < _RESET:  # more than 2^28 in a second: stats were reset, skip
            self._acc_frames += df - (self._acc_frames >> 3)
            self._acc_lost += dl - (self._acc_lost >> 3)
        total = self._acc_frames + self._acc_lost
        self.drop_rate_comm = self._acc_lost * 10000 // total if total else 0

    def _check_gcs(self, now):
        state = self._gcs_state
        i = 0
        while i < len(self.ep.links):  # a link's index is its place in ep.links
            if state[i] == _GCS_PRESENT and ticks_diff(now, self._gcs_seen[i]) > self.gcs_timeout_ms:
                state[i] = _GCS_LOST
                if self.on_gcs_lost is not None:
                    self.on_gcs_lost(self.ep.links[i])
            i += 1
        if self.operator is not None:
            self.operator.check(now)

    # --- incoming -------------------------------------------------------------
    def _on_heartbeat(self, link, p):
        now = self.ep.now
        if self.operator is not None:
            self.operator.heartbeat(link, now)
        if p[4] != _MAV_TYPE_GCS:
            return
        i = link.index
        if i >= len(self._gcs_state):
            return  # a link added after start-up; tick() sizes the tables
        self._gcs_seen[i] = now
        if self._gcs_state[i] != _GCS_PRESENT:
            self._gcs_state[i] = _GCS_PRESENT
            if self.on_gcs_regained is not None:
                self.on_gcs_regained(link)

    def _on_ping(self, link, p):
        # target 0/0 is a request; anything else is someone's answer.
        if p[12] or p[13]:
            return
        off = link.begin()
        buf = link.txbuf
        copy(buf, p, off, 12)  # time_usec and seq as received
        buf[off + 12] = link.rx.sysid
        buf[off + 13] = link.rx.compid
        link.rank = RANK_OTHER  # a cheap one-off: beyond the budget it is dropped
        link.send(_MSG_PING)
        link.rank = RANK_AUTO

    def _on_system_time(self, link, p):
        # A ground station's clock is better than none; the application's wins.
        if self._clock_from_app:
            return
        self.ep.clock.set_unix(p, 0)

    def _on_set_mode(self, link, p):
        if p[4] != self.ep.sysid:
            return
        if not self.ep.allows(link):
            self.statustext(WARNING, b"Mode: GCS not in control")
            return
        custom = u32(p, 0)
        self.modes.heard_custom(link, custom)
        self.set_mode(p[5], custom)

    def _on_operator_control(self, link, p):
        on_change_operator_control(self.ep, link, p, self.operator)

    # --- producers: send(link) -> bool -----------------------------------------
    # Packed a few fields at a time over a cleared payload: a struct.pack_into of a
    # whole message puts more values on the stack than a frame state MicroPython
    # keeps off the heap (about 11 words).
    def send_heartbeat(self, link):
        custom = self.modes.custom(link)  # as this link's ground station numbers modes
        off = link.begin()
        buf = link.txbuf
        pack_into("<I", buf, off, custom)
        buf[off + 4] = self.mav_type
        buf[off + 5] = self.autopilot
        buf[off + 6] = self.base_mode
        buf[off + 7] = self.system_status
        buf[off + 8] = _MAVLINK_VERSION
        return link.send(_MSG_HEARTBEAT)

    def send_sys_status(self, link):
        # _SYS_STATUS_FMT; errors_count2..4 stay 0.
        off = link.tx.clear(link.tx.crc_len[_MSG_SYS_STATUS] >> 16)
        buf = link.txbuf
        pack_into("<III", buf, off, self.sensors_present, self.sensors_enabled, self.sensors_health)
        _merge(buf, off, self._own_present)  # enabled: what is present
        _merge(buf, off + 4, self._own_present)
        _merge(buf, off + 8, self._own_health)
        pack_into("<HHh", buf, off + 12, self.load, self.voltage_mv, self.current_ca)
        pack_into("<HH", buf, off + 18, self.drop_rate_comm, self.errors_comm)
        pack_into("<H", buf, off + 22, self.texts.dropped & 0xFFFF)  # errors_count1
        pack_into("<b", buf, off + 30, self.battery_remaining)
        return link.send(_MSG_SYS_STATUS)

    def send_system_time(self, link):
        off = link.begin()
        clock = self.ep.clock
        clock.stamp_unix(link.txbuf, off)
        clock.stamp_ms(link.txbuf, off + 8)
        return link.send(_MSG_SYSTEM_TIME)

    def send_autopilot_version(self, link):
        # _AUTOPILOT_VERSION_FMT: capabilities, uid, flight_sw_version, middleware 0,
        # os_sw_version; board_version, vendor_id, product_id and the hashes stay 0.
        off = link.tx.clear(link.tx.crc_len[_MSG_AUTOPILOT_VERSION] >> 16)
        buf = link.txbuf
        pack_into("<QQI", buf, off, self.ep.capabilities, self.uid, self._sw_version)
        pack_into("<I", buf, off + 24, self._os_version)
        return link.send(_MSG_AUTOPILOT_VERSION)

    def send_home_position(self, link):
        # _HOME_POSITION_FMT: lat, lon, alt; x, y, z 0; q = (1, 0, 0, 0); the rest 0.
        if not self.home_set or _MSG_HOME_POSITION not in link.tx.crc_len:
            return False  # (the seed's message set has no HOME_POSITION)
        off = link.tx.clear(link.tx.crc_len[_MSG_HOME_POSITION] >> 16)
        buf = link.txbuf
        pack_into("<iii", buf, off, self.home_lat, self.home_lon, self.home_alt)
        pack_into("<f", buf, off + 24, self._one)
        return link.send(_MSG_HOME_POSITION)


def _capped(n):
    return n if n < 0xFFFF else 0xFFFF


def _merge(buf, o, bits):
    # The status service's bits (only _OWN_BIT of bytes 2 and 3) into a uint32 at o.
    buf[o + 2] = (buf[o + 2] & ~_OWN_BIT) | (bits >> 16 & _OWN_BIT)
    buf[o + 3] = (buf[o + 3] & ~_OWN_BIT) | (bits >> 24 & _OWN_BIT)


def _version_word(v, kind):
    return v[0] << 24 | v[1] << 16 | v[2] << 8 | kind


def _os_version():
    import sys

    return _version_word(sys.implementation.version, _FIRMWARE_VERSION_TYPE_DEV)


def _uid(board, sysid):
    uid = getattr(board, "UID", 0)
    if not uid:
        try:
            import machine

            uid = int.from_bytes(machine.unique_id()[:8], "little")
        except (ImportError, AttributeError):
            uid = 0
    return uid or sysid


def create(ep):
    board = getattr(ep, "board", None)
    status = Status(
        mav_type=ep.setting("MAV_TYPE", 2),
        autopilot=ep.setting("MAV_AUTOPILOT", 0),
        gcs_timeout_ms=ep.setting("GCS_TIMEOUT_MS", 5000),
        passkey=ep.setting("OPERATOR_PASSKEY") or None,
        uid=_uid(board, ep.sysid),
        reboot_delay_ms=ep.setting("REBOOT_DELAY_MS", 100),
    )
    status.mode_flags_supported = ep.setting("MODE_FLAGS", status.mode_flags_supported)
    status.modes = Modes(ep.setting("FLIGHT_MODES", None) or ep.setting("CUSTOM_MODES", ()),
                         ep.setting("MODE_NUMBERING", "auto"))
    ep.add(status)
    if status.modes.table:
        status.enter(max(status.modes.by_number(0), 0), False)  # boots in the mode numbered 0
    return status
