"""The status service: the vehicle's identity and state (HEARTBEAT), the state other
services and the application share (status.armed, status.flight_mode, status.home ...)
and the hooks the application sets (arm_check, mode_check, on_gcs_lost ...), arming, the
clock (SYSTEM_TIME), PING, STATUSTEXT and the reboot on its way. Its other jobs are
modules beside it, made here: health.py (SYS_STATUS, the ground station each link hears),
conventions.py (ArduPilot's or PX4's, per link), modes.py (flight modes), operator.py
(operator control) and vehicle_commands.py (the vehicle's own commands,
AUTOPILOT_VERSION, HOME_POSITION).
Reference: docs/services/status.md
"""
from struct import pack_into

from ...compat import const, ticks_diff, ticks_add, to_grid
from ...endpoint import REBOOT, SHUTDOWN
from ...kernels import copy
from ...link import RANK_VITAL, RANK_OTHER, RANK_AUTO
from ...statustext import TextQueue, NOTICE
from .conventions import Conventions
from .health import Health
from .modes import Modes, veto
from .operator import Operator, on_change_operator_control
from . import vehicle_commands

# the fence plan; who sends SYS_STATUS; signing commands; ACKs a reboot waits for
USES = ("missions", "streams", "signing", "commands")


# MAV_STATE
MAV_STATE_BOOT = const(1)
MAV_STATE_STANDBY = const(3)
MAV_STATE_ACTIVE = const(4)
MAV_STATE_CRITICAL = const(5)
MAV_STATE_EMERGENCY = const(6)
# MAV_MODE_FLAG
MODE_ARMED = const(128)
MODE_HIL = const(32)
MODE_STABILIZE = const(16)
MODE_GUIDED = const(8)
MODE_AUTO = const(4)
MODE_CUSTOM = const(1)

_ACCEPTED = const(0)
_DENIED = const(2)

_MSG_HEARTBEAT = const(0)
_MSG_SYS_STATUS = const(1)
_MSG_SYSTEM_TIME = const(2)
_MSG_PING = const(4)
_MSG_CHANGE_OPERATOR_CONTROL = const(5)
_MSG_HOME_POSITION = const(242)
_CAP_MAVLINK2 = const(8192)
_MAVLINK_VERSION = const(3)

_PERIOD_MS = const(1000)  # HEARTBEAT, and SYS_STATUS when no streams service schedules it
_WAIT_MS = const(100)
_TEXT_FRAME = const(66)  # bytes of a MAVLink 2 STATUSTEXT, for pacing on slow links
_TEXT_SHARE = const(4)  # STATUSTEXT may use a quarter of the slowest link


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
        # The state (modes.py changes mode, custom_mode, flight_mode and hil)
        self.armed = False
        self.mode = 0  # MAV_MODE_FLAG bits but SAFETY_ARMED
        self.base_mode = 0
        self.custom_mode = 0
        self.system_status = MAV_STATE_BOOT
        self.flight_mode = None
        self.hil = False  # MAV_MODE_FLAG_HIL_ENABLED, on a board whose MODE_FLAGS allow it
        self.reason = None  # why the last arming or mode request was refused
        self._airborne = -1  # set_airborne: 1 in the air, 0 on the ground, -1 not told
        self._override = 0  # a MAV_STATE the application set, 0: follow the life cycle
        self._initialised = False
        # Hooks the application may set (docs/services/status.md): vetoes, a position, events
        self.arm_check = self.mode_check = self.flight_mode_check = self.position = None
        self.on_gcs_lost = self.on_gcs_regained = self.on_hil = self.on_arm = self.on_flight_mode = None
        # SYS_STATUS figures: the application's, and what health.py measures
        self.sensors_present = self.sensors_enabled = self.sensors_health = 0
        self.fence_enabled = False
        self.fence_breached = False
        self.voltage_mv = 0xFFFF  # UINT16_MAX: not measured
        self.current_ca = -1
        self.battery_remaining = -1
        self.load = 0
        self.drop_rate_comm = 0
        self.errors_comm = 0
        # Home
        self.home_set = False
        self.home_lat = self.home_lon = self.home_alt = 0
        self._home_changed = False
        self._clock_from_app = False  # the time of day came from the application (ep.clock)
        self._next_period = 0
        self._gcs_ms = 0  # until a ground station may be lost (health.check_gcs)
        self._next_text = 0
        self._text_gap_ms = 0
        self.rebooting = 0  # the action on its way: 1 reboot, 2 shutdown; 0 none
        self._reboot_at = 0
        self.texts = TextQueue(text_slots)
        self.conventions = Conventions()
        self.modes = Modes(())
        self.health = Health(self)
        # idle(ms, sleep=None): the loop's sleep, counted as idle time for SYS_STATUS.load;
        # add_idle(us): time waited elsewhere. Health's own (the loop's one call a pass).
        self.idle = self.health.idle
        self.add_idle = self.health.add_idle
        self.operator = None
        self.ep = None

    # --- wiring ---------------------------------------------------------------
    def attach(self, ep):
        self.ep = ep
        now = ep.now
        self._next_period = now
        self._next_text = now
        self._links_changed()
        ep.capabilities |= _CAP_MAVLINK2
        ep.on(_MSG_HEARTBEAT, self._on_heartbeat)
        self.conventions.attach(ep)
        self.modes.attach(ep, self)
        ep.on(_MSG_PING, self._on_ping)
        ep.on(_MSG_SYSTEM_TIME, self._on_system_time)
        ep.on(_MSG_CHANGE_OPERATOR_CONTROL, on_change_operator_control)
        ep.producers[_MSG_HEARTBEAT] = self.send_heartbeat
        ep.producers[_MSG_SYS_STATUS] = self.health.send_sys_status
        ep.producers[_MSG_SYSTEM_TIME] = self.send_system_time
        if self.passkey:
            self.operator = Operator(ep, self.passkey, self.gcs_timeout_ms)
            ep.operator = self.operator
        vehicle_commands.install(ep, self)  # and AUTOPILOT_VERSION, HOME_POSITION
        # Announce BOOT at once: a ground station already listening sees the vehicle come up.
        for link in ep.links:
            self.send_heartbeat(link)

    def _links_changed(self):
        # Rare (start-up): size the per-link tables and the STATUSTEXT pacing.
        links = self.ep.links
        self.conventions.links_changed(links)
        self.health.links_changed(links)
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

    def update_state(self):
        """base_mode and system_status (HEARTBEAT's) from the state, after a change."""
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
        self.update_state()

    def set_state(self, state):
        """Report a MAV_STATE (e.g. CRITICAL, EMERGENCY) until set_state(0)."""
        self._override = state
        self.update_state()

    def arm(self, arm, force=False):
        """Arm (True) or disarm -> MAV_RESULT; on refusal self.reason says why."""
        self.reason = None
        arm = bool(arm)
        if arm == self.armed:
            return _ACCEPTED
        if not force and self.arm_check is not None:
            result = veto(self, self.arm_check(arm), b"Arm: " if arm else b"Disarm: ")
            if result != _ACCEPTED:
                return result
        self.armed = arm
        self.update_state()
        if self.on_arm is not None:
            self.on_arm(arm)  # before the answer: the next command sees what follows
        return _ACCEPTED

    def set_mode(self, base_mode, custom_mode=0):
        """A ground station's mode request -> MAV_RESULT (modes.py)."""
        return self.modes.set_mode(base_mode, custom_mode)

    def set_flight_mode(self, name):
        """The application changes mode (a failsafe, a takeoff done) -> MAV_RESULT."""
        row = self.modes.by_name(name)
        return self.modes.enter(row, False) if row >= 0 else _DENIED

    def set_home(self, lat_e7, lon_e7, alt_mm):
        self.home_lat = int(lat_e7)
        self.home_lon = int(lon_e7)
        self.home_alt = int(alt_mm)
        self.home_set = True
        self._home_changed = True  # ground stations learn it from HOME_POSITION, at once
        if self.ep is not None:
            self.ep.wake()

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
        if self.ep is not None:
            self.ep.wake()  # sent on the next pass

    def gcs_present(self, link):
        """Does this link hear a ground station (its heartbeats, within gcs_timeout_ms)?"""
        return self.health.gcs_present(link)

    def reboot(self, action=1):
        """Reboot (1) or shut down (2) after reboot_delay_ms, so the ACK gets out first."""
        self.rebooting = action
        self._reboot_at = ticks_add(self.ep.now, self.reboot_delay_ms)
        self.statustext(NOTICE, b"Rebooting" if action == 1 else b"Shutting down")

    # --- periodic work (links by index: see docs/design.md) -------------------
    def tick(self, now):
        if not self._initialised:
            self._initialised = True
            self.modes.wrap_request_message()
            self.update_state()
        if self.modes.changed:
            self.modes.announce()
        if self.health.link_count < len(self.ep.links):
            self._links_changed()
        if ticks_diff(now, self._next_period) >= 0:
            self._period(now)
        self._gcs_ms = self.health.check_gcs(now)
        if self.operator is not None:
            self.operator.check(now)
        if self._home_changed:
            self._home_changed = False
            self.send_all(_MSG_HOME_POSITION)
        if self.texts.count and ticks_diff(now, self._next_text) >= 0:
            self._next_text = ticks_add(now, self._text_gap_ms)
            for link in self.ep.links:
                self.texts.send(link)
            self.texts.pop()
        if self.rebooting and vehicle_commands.reboot_due(self.ep, self._reboot_at, now):
            action = self.rebooting
            self.rebooting = 0
            if action == 2:
                self.ep.board.shutdown()
                raise SHUTDOWN
            raise REBOOT
        return self._wait(now)

    def _wait(self, now):
        """ms to the next work: the period, a ground station's loss, a text's turn, the
        reboot; at most _WAIT_MS with operator control (its release is checked then)."""
        ms = ticks_diff(self._next_period, now)
        if self._gcs_ms < ms:
            ms = self._gcs_ms
        if self.operator is not None and _WAIT_MS < ms:
            ms = _WAIT_MS
        if self.texts.count and ticks_diff(self._next_text, now) < ms:
            ms = ticks_diff(self._next_text, now)
        if self.rebooting and ticks_diff(self._reboot_at, now) < ms:
            ms = ticks_diff(self._reboot_at, now)
            if ms <= 0:
                ms = 10  # due, its held-back ACKs not yet out (vehicle_commands.reboot_due)
        return ms

    def send_all(self, msgid):
        """A rare message (a change to announce) to every link."""
        send = self.ep.producers.get(msgid)
        if send is not None:
            for link in self.ep.links:
                send(link)

    def _period(self, now):
        # Once a second: HEARTBEAT, and SYS_STATUS unless the streams service schedules it.
        # The next second on the loop's grid (a pass late or early keeps it; one that
        # fell behind keeps the rate, not the backlog).
        self._next_period = ticks_add(now, to_grid(now, _PERIOD_MS))
        self.health.measure()
        sys_status = "streams" not in self.ep.services
        for link in self.ep.links:
            link.rank = RANK_VITAL  # the 1 Hz HEARTBEAT goes whatever else the link carries
            self.send_heartbeat(link)
            link.rank = RANK_AUTO
            if sys_status:
                self.health.send_sys_status(link)

    # --- incoming -------------------------------------------------------------
    def _on_heartbeat(self, link, p):
        if self.operator is not None:
            self.operator.heartbeat(link, self.ep.now)
        self.health.heard(link, p)

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

    # --- producers: send(link) -> bool, a few fields a pack_into (docs/design.md) ---
    def send_heartbeat(self, link):
        # custom_mode as this link's ground station reads it (modes.py)
        custom = self.modes.custom_for(link, self.modes.row, self.custom_mode)
        off = link.begin()
        buf = link.txbuf
        pack_into("<I", buf, off, custom)
        buf[off + 4] = self.mav_type
        buf[off + 5] = self.autopilot
        buf[off + 6] = self.base_mode
        buf[off + 7] = self.system_status
        buf[off + 8] = _MAVLINK_VERSION
        return link.send(_MSG_HEARTBEAT)

    def send_system_time(self, link):
        off = link.begin()
        clock = self.ep.clock
        clock.stamp_unix(link.txbuf, off)
        clock.stamp_ms(link.txbuf, off + 8)
        return link.send(_MSG_SYSTEM_TIME)


def create(ep):
    board = getattr(ep, "board", None)
    status = Status(
        mav_type=ep.setting("MAV_TYPE", 2),
        autopilot=ep.setting("MAV_AUTOPILOT", 0),
        gcs_timeout_ms=ep.setting("GCS_TIMEOUT_MS", 5000),
        passkey=ep.setting("OPERATOR_PASSKEY") or None,
        uid=vehicle_commands.board_uid(board, ep.sysid),
        reboot_delay_ms=ep.setting("REBOOT_DELAY_MS", 100),
    )
    status.modes = Modes(ep.setting("FLIGHT_MODES", None) or ep.setting("CUSTOM_MODES", ()),
                         ep.setting("MODE_NUMBERING", "auto"),
                         ep.setting("MODE_FLAGS", status.modes.flags_supported))
    ep.add(status)
    modes = status.modes
    if modes.table:
        modes.enter(max(modes.by_number(0), 0), False)  # boots in the mode numbered 0
    return status
