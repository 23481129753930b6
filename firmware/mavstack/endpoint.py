"""The endpoint: a vehicle's MAVLink identity, its links, and dispatch by message id.

Services (heartbeat, parameters, commands, missions, streams, ...) are optional
modules composed per board: each attaches to the endpoint, registers the message
ids it handles with `on()`, and, if it has periodic work, a `tick(now_ms)` that
says in how many ms it next has work (None: every pass). poll() runs a tick when
it is due, or after a frame came in; wait_ms says how long the loop may sleep.
Reference: docs/core.md.
"""
from .compat import const, ticks_ms, ticks_add, ticks_diff
from .faults import Faults, MESSAGE, TICK, LINK
from .link import Link


class Reboot(Exception):
    """Raised out of poll() once a reboot was acknowledged; main.py restarts the board."""


class Shutdown(Exception):
    """Raised out of poll() once a shutdown was acknowledged; main.py returns."""


WAIT_MAX_MS = const(250)  # the longest poll() lets the loop sleep (the watchdog is fed between)
_FAR_MS = const(60000)  # no ticker asks to wait this long
_ALL = const(-2)  # a frame wakes every ticker
_NONE = const(-1)  # ... none
_SLACK_MS = const(10)  # a ticker due this soon runs with those due now (streams.md)

# Raised as made here, once: making an exception allocates, and the heap may be locked.
REBOOT = Reboot()
SHUTDOWN = Shutdown()


class Endpoint:
    _clock = None  # made by the first service that tells the time (see clock)

    def __init__(self, dialect, sysid=1, compid=1):
        self.dialect = dialect
        self.sysid = sysid
        self.compid = compid
        self.links = []
        self.now = self._born = ticks_ms()
        # msgid -> (the ticker its frames wake (_ALL, _NONE), handler(link, payload), ...)
        self._handlers = {}
        self._owner = _ALL  # the ticker of the service attaching now
        self.tickers = []  # services with periodic work, in the order they were added
        self._due = []  # ticks_ms at which each ticker next has work
        self._next = self.now  # ... the first of them
        self.heard = False  # a frame came in (or wake()): every ticker runs on this pass
        self.all_due = False  # ... this pass's (the loop ticks its application then too)
        self.wait_ms = 0  # how long the loop may sleep after this pass (poll sets it)
        self.services = {}
        self.faults = Faults(self, (Reboot, Shutdown))  # what a handler or tick raised: faults.py
        # Shared between services, filled as they attach:
        self.capabilities = 0  # MAV_PROTOCOL_CAPABILITY bits for AUTOPILOT_VERSION
        self.producers = {}  # msgid -> send(link): one message now (REQUEST_MESSAGE, streams)
        self.commands = {}  # MAV_CMD id -> handler(cmd) -> MAV_RESULT (services/commands/)
        self.operator = None  # gate with allows(link), set by operator control
        self.router = None  # routing between links (router.py), added by main.py

    def add_link(self, transport, version=0):
        link = Link(self, transport, len(self.links), version)
        self.links.append(link)
        return link

    @property
    def clock(self):
        """Uptime and time of day as bytes (uptime.py), counted from the endpoint's start.
        Made when the first service attaches that does not say CLOCK = False, or on first
        use: a board whose services never tell the time (missions only) does without it."""
        if self._clock is None:
            from .uptime import Clock

            self._clock = Clock(self._born)
            self._clock.advance(self.now)
        return self._clock

    @clock.setter
    def clock(self, clock):
        self._clock = clock

    def add(self, service, name=None):
        """Attach a service; it registers its messages in its attach(endpoint)."""
        self.services[name or service.NAME] = service
        if getattr(service, "CLOCK", True):
            self.clock  # made now, at start-up, rather than on a hot path
        # The frames it registers for wake its tick alone (WAKE_ALL: every tick; see poll).
        self._owner = _ALL if getattr(service, "WAKE_ALL", False) else (
            len(self.tickers) if hasattr(service, "tick") else _NONE)
        service.attach(self)
        self._owner = _ALL  # (a handler registered later, by the application)
        if hasattr(service, "tick"):
            self.tickers.append(service)
            self._due.append(self.now)
        return service

    def on(self, msgid, handler, wake=True):
        """Call handler(link, payload) for every frame with this id (if the dialect has it).
        wake=False: its frames do not wake the service's tick (a handler that leaves the
        tick work says so, ep.wake(service)): a mission item's pass skips every tick."""
        if msgid not in self.dialect.CRC_LEN:
            return False
        # A tuple: one small object per message id (a list takes two), the ticker first.
        owner = self._owner if wake else _NONE
        was = self._handlers.get(msgid, (_NONE,))
        w = was[0]
        w = owner if w in (_NONE, owner) else (w if owner == _NONE else _ALL)
        self._handlers[msgid] = (w,) + was[1:] + (handler,)
        return True

    def setting(self, name, default=None):
        """A board setting: `--set name=V` (lower case) over the profile's NAME over default."""
        value = (getattr(self, "options", None) or {}).get(name.lower())
        if value is None:
            return getattr(getattr(self, "board", None), name, default)
        if isinstance(default, bool):
            return value not in ("0", "false", "no", "")
        if isinstance(default, int):
            return int(value)
        if isinstance(default, float):
            return float(value)
        return value

    def has(self, msgid):
        return msgid in self.dialect.CRC_LEN

    def fmt(self, msgid):
        """struct format of a message's full payload, from the dialect."""
        return self.dialect.FMT[msgid]

    def for_us(self, target_system, target_component):
        """True when a message's target is this vehicle (0 is broadcast): our system and
        component 0 or ours, or, with routing, a component of ours heard on no link."""
        if target_system != 0 and target_system != self.sysid:
            return False
        if target_component == 0 or target_component == self.compid:
            return True
        return self.router is not None and self.router.unseen(target_component)

    def allows(self, link):
        """May the ground station on this link change parameters, missions or arm?"""
        return self.operator is None or self.operator.allows(link)

    def statustext(self, severity, text):
        """Queue a STATUSTEXT for every link (services report refusals this way)."""
        status = self.services.get("status")
        if status is not None:
            status.statustext(severity, text)

    def dispatch(self, link, msgid, payload):
        """Hand a frame to its handlers; one that raises is a fault (counted, reported)
        and the frame goes on to the others."""
        handlers = self._handlers.get(msgid)
        if handlers is not None:
            # A frame with handlers: their service's tick runs on this pass (it may have
            # been left work), or every tick, or none (on(wake=False)). (i reused: few locals.)
            i = handlers[0]
            if i == _ALL:
                self.heard = True
            elif i >= 0:
                self._due[i] = self.now
                self._next = self.now
            self.faults.payload = payload
            i = 1  # by index: see docs/design.md
            while i < len(handlers):
                self.faults.deliver(handlers[i], link)
                if self.faults.error is not None:
                    self.faults.count(MESSAGE, msgid)
                i += 1

    def wake(self, service=None):
        """Ticks run on the next pass, at once: the service's, or every one (work made
        outside a frame for them: an application's call, another service's)."""
        self.wait_ms = 0
        if service is None:
            self.heard = True
            return
        i = 0
        while i < len(self.tickers):
            if self.tickers[i] is service:
                self._due[i] = self.now
                self._next = self.now
            i += 1

    def poll(self, now=None):
        """One pass of the main loop: read every link, then run the service work that is
        due (all of it after a frame came in). A link or a service that raises is a
        fault: the others go on. Then wait_ms says when the next work is due.

        Never blocks; call it from a plain loop or wrap it in asyncio.
        """
        if now is None:
            now = ticks_ms()
        self.now = now
        faults = self.faults
        i = 0
        while i < len(self.links):
            faults.poll(self.links[i])
            if faults.error is not None:
                faults.count(LINK, i)
            i += 1
        if self._clock is not None:
            self._clock.advance(now)
        self.all_due = self.heard
        self.heard = False
        ms = ticks_diff(self._next, now)
        if not self.all_due and 0 < ms < _FAR_MS:
            self.wait_ms = ms  # no ticker is due: the cheap pass
        else:
            self._ticks(now)
        if self.heard:  # woken meanwhile
            self.wait_ms = 0
        if faults.owed:  # a fault to report (at most one every REPORT_MS)
            faults.report(now)
            if faults.owed:
                self.until(faults.report_at(now))

    def _ticks(self, now):
        # A ticker due within _SLACK_MS runs now too: fewer passes wake the loop. (Every
        # pass with work comes here: few operations an iteration.)
        self.wait_ms = WAIT_MAX_MS
        due = self._due
        n = len(due)
        i = 0
        while i < n:
            ms = ticks_diff(due[i], now)
            if ms <= _SLACK_MS or ms >= _FAR_MS or self.all_due:  # (farther: the clock jumped)
                self._tick(i, now)
            elif ms < self.wait_ms:
                self.wait_ms = ms
            i += 1
        self._next = ticks_add(now, self.wait_ms)  # the first ticker due

    def _tick(self, i, now):
        # (small functions: docs/design.md)
        faults = self.faults
        ms = faults.tick(self.tickers[i], now)
        if faults.error is not None:
            faults.count(TICK, i)
            ms = 1
        elif ms is None:
            ms = 1
        self._due[i] = ticks_add(now, ms)
        if ms < self.wait_ms:  # (until(ms), without the call)
            self.wait_ms = ms if ms > 0 else 0

    def until(self, ms):
        """The loop may sleep at most ms after this pass."""
        if ms < self.wait_ms:
            self.wait_ms = ms if ms > 0 else 0

    def close(self):
        for link in self.links:
            link.transport.close()
