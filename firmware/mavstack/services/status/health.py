"""The vehicle's health and its links': SYS_STATUS, from the status service's figures
(the application's sensors and battery), the loop's load, the links' drop rate and
errors, and the two sensor bits filled here (pre-arm check, geofence); and the ground
station each link hears, by its heartbeats (status.on_gcs_lost and on_gcs_regained fire
from here; a station heard anew gets a HEARTBEAT at once). Made by the status service (status.health).
Reference: docs/services/status.md
"""
from struct import pack_into

from ...compat import const, ticks_us, ticks_diff, sleep_ms
from ...parser import COUNT_WRAP

# MAV_SYS_STATUS bits filled here, merged into the application's words as bytes, so its
# masks may use bit 31.
_PREARM_CHECK = const(0x10000000)  # byte 3, 0x10
_GEOFENCE = const(0x100000)  # byte 2, 0x10
_OWN_BIT = const(0x10)  # the bit each of them is in its byte
_FENCE_PLAN = const(1)  # missions.stores[1]: the fence

_MSG_SYS_STATUS = const(1)
_MAV_TYPE_GCS = const(6)
_GCS_NEVER = const(0)  # no GCS heartbeat yet on this link (the tables start zeroed)
_GCS_PRESENT = const(1)
_GCS_LOST = const(2)
_ACCEPTED = const(0)
_RESET = const(0x10000000)  # half of the counters' modulus (parser.COUNT_WRAP + 1)


class Health:
    def __init__(self, status):
        self.status = status
        self._own_present = _PREARM_CHECK  # the bits above, as of the last _own_bits()
        self._own_health = _PREARM_CHECK | _GEOFENCE
        # Load and link figures, per window
        self._win_us = ticks_us()
        self._idle_us = -1  # idle time this window, -1: none told (the load stays as it was)
        self._frames = 0
        self._lost = 0
        self._acc_frames = 0
        self._acc_lost = 0
        # Ground stations, per link (by its index)
        self.link_count = 0  # links the tables are sized for
        self._gcs_seen = []  # ticks_ms of the last heartbeat
        self._gcs_state = bytearray(0)  # _GCS_NEVER, _GCS_PRESENT or _GCS_LOST

    def idle(self, ms, sleep=None):
        """sleep(ms) (sleep_ms by default: the loop's may end early), counted as idle
        time for SYS_STATUS.load."""
        t = ticks_us()
        (sleep or sleep_ms)(ms)
        if self._idle_us < 0:  # (add_idle, inline: once a pass)
            self._idle_us = 0
        self._idle_us += ticks_diff(ticks_us(), t)

    def add_idle(self, us):
        if self._idle_us < 0:
            self._idle_us = 0
        self._idle_us += us

    def measure(self):
        """Once a second: the load, the link figures and the two own bits."""
        t = ticks_us()
        wall = ticks_diff(t, self._win_us)
        if self._idle_us >= 0 and wall > 0:
            busy = (wall - self._idle_us) * 1000 // wall
            self.status.load = 0 if busy < 0 else 1000 if busy > 1000 else busy
        self._win_us = t
        self._idle_us = -1
        self._link_figures()
        self._own_bits()

    def _own_bits(self):
        # What the arming check and the fence say.
        status = self.status
        present = _PREARM_CHECK
        health = _PREARM_CHECK if status.armed or self._prearm_ok() else 0
        if status.fence_enabled and self._fence_plan():
            present |= _GEOFENCE
        if not status.fence_breached:
            health |= _GEOFENCE
        self._own_present = present
        self._own_health = health

    def _prearm_ok(self):
        if self.status.arm_check is None:
            return True
        try:
            answer = self.status.arm_check(True)
        except Exception:  # a broken check is no green light
            return False
        return answer is None or (isinstance(answer, tuple) and answer[0] == _ACCEPTED)

    def _fence_plan(self):
        missions = self.status.ep.services.get("missions")
        store = missions.stores[_FENCE_PLAN] if missions is not None else None
        return store is not None and store.count > 0

    def _link_figures(self):
        # The parser's counters wrap at parser.COUNT_WRAP: sums and differences are taken
        # modulo that (docs/design.md: 32-bit clean).
        frames = lost = errors = 0
        i = 0
        while i < len(self.status.ep.links):  # by index: see docs/design.md
            rx = self.status.ep.links[i].rx
            frames = (frames + rx.frames) & COUNT_WRAP
            lost = (lost + rx.lost) & COUNT_WRAP
            errors = _capped(_capped(errors + _capped(rx.crc_errors)) + _capped(rx.bad_frames))
            i += 1
        self._smooth((frames - self._frames) & COUNT_WRAP, (lost - self._lost) & COUNT_WRAP)
        self._frames = frames
        self._lost = lost
        self.status.errors_comm = errors

    def _smooth(self, df, dl):
        if df < _RESET and dl < _RESET:  # more than 2^28 in a second: stats were reset, skip
            self._acc_frames += df - (self._acc_frames >> 3)
            self._acc_lost += dl - (self._acc_lost >> 3)
        total = self._acc_frames + self._acc_lost
        self.status.drop_rate_comm = self._acc_lost * 10000 // total if total else 0

    # --- ground stations present -----------------------------------------------------
    def links_changed(self, links):
        # Rare (start-up): one entry a link.
        while len(self._gcs_seen) < len(links):
            self._gcs_seen.append(0)
            self._gcs_state = self._gcs_state + b"\0"
        self.link_count = len(links)

    def gcs_present(self, link):
        i = link.index
        return i < self.link_count and self._gcs_state[i] == _GCS_PRESENT

    def heard(self, link, p):
        # A HEARTBEAT: a ground station's marks its link.
        i = link.index
        if p[4] != _MAV_TYPE_GCS or i >= self.link_count:
            return  # (a link added after start-up: the status service's tick sizes the tables)
        self._gcs_seen[i] = self.status.ep.now
        if self._gcs_state[i] != _GCS_PRESENT:
            self._gcs_state[i] = _GCS_PRESENT
            # A HEARTBEAT at once: a station that waits briefly for one after its own (as
            # MAVProxy does before asking for streams) finds the vehicle now.
            self.status.send_heartbeat(link)
            if self.status.on_gcs_regained is not None:
                self.status.on_gcs_regained(link)

    def check_gcs(self, now):
        """Every tick: a link whose ground station fell silent has lost it -> ms until
        the next may be lost (the status service's tick is due by then)."""
        state = self._gcs_state
        first = self.status.gcs_timeout_ms
        i = 0
        while i < self.link_count:  # a link's index is its place in ep.links
            if state[i] == _GCS_PRESENT:
                left = self.status.gcs_timeout_ms - ticks_diff(now, self._gcs_seen[i])
                if left < 0:
                    self._gcs_lost(i)
                elif left < first:
                    first = left
            i += 1
        return first + 1

    def _gcs_lost(self, i):
        self._gcs_state[i] = _GCS_LOST
        if self.status.on_gcs_lost is not None:
            self.status.on_gcs_lost(self.status.ep.links[i])

    # --- producer: send(link) -> bool -------------------------------------------------
    def send_sys_status(self, link):
        # "<IIIHHhHHHHHHb", a few fields a pack_into (docs/design.md); errors_count2..4 are
        # the faults contained (faults.py): handlers, periodic work, application and links.
        off = link.tx.clear(link.tx.crc_len[_MSG_SYS_STATUS] >> 16)
        buf = link.txbuf
        pack_into("<III", buf, off, self.status.sensors_present, self.status.sensors_enabled,
                  self.status.sensors_health)
        _merge(buf, off, self._own_present)  # enabled: what is present
        _merge(buf, off + 4, self._own_present)
        _merge(buf, off + 8, self._own_health)
        pack_into("<HHh", buf, off + 12, self.status.load, self.status.voltage_mv, self.status.current_ca)
        pack_into("<HH", buf, off + 18, self.status.drop_rate_comm, self.status.errors_comm)
        pack_into("<H", buf, off + 22, self.status.texts.dropped & 0xFFFF)  # errors_count1
        _faults(buf, off + 24, self.status.ep.faults.counts)
        pack_into("<b", buf, off + 30, self.status.battery_remaining)
        return link.send(_MSG_SYS_STATUS)


def _capped(n):
    return n if n < 0xFFFF else 0xFFFF


def _faults(buf, o, counts):
    # errors_count2..4 from faults.counts (by kind, in pairs: faults.MESSAGE and COMMAND,
    # TICK and PRODUCER, APP and LINK), each capped at UINT16_MAX.
    i = 0
    while i < 6:
        n = _capped(counts[i] + counts[i + 1])
        buf[o] = n & 0xFF
        buf[o + 1] = n >> 8
        o += 2
        i += 2


def _merge(buf, o, bits):
    # The bits filled here (only _OWN_BIT of bytes 2 and 3) into a uint32 at o.
    buf[o + 2] = (buf[o + 2] & ~_OWN_BIT) | (bits >> 16 & _OWN_BIT)
    buf[o + 3] = (buf[o + 3] & ~_OWN_BIT) | (bits >> 24 & _OWN_BIT)
