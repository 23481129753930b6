"""The endpoint: a vehicle's MAVLink identity, its links, and dispatch by message id.

Services (heartbeat, parameters, commands, missions, streams, ...) are optional
modules composed per board: each attaches to the endpoint, registers the message
ids it handles with `on()`, and, if it has periodic work, a `tick(now_ms)`.
Reference: docs/core.md.
"""
from .compat import ticks_ms
from .faults import Faults, MESSAGE, TICK, LINK
from .link import Link


class Reboot(Exception):
    """Raised out of poll() once a reboot was acknowledged; main.py restarts the board."""


class Shutdown(Exception):
    """Raised out of poll() once a shutdown was acknowledged; main.py returns."""


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
        self._handlers = {}  # msgid -> (handler(link, payload), ...)
        self.tickers = []  # services with periodic work, in the order they were added
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
        service.attach(self)
        if hasattr(service, "tick"):
            self.tickers.append(service)
        return service

    def on(self, msgid, handler):
        """Call handler(link, payload) for every frame with this id (if the dialect has it)."""
        if msgid not in self.dialect.CRC_LEN:
            return False
        # A tuple: one small object per message id (a list takes two).
        self._handlers[msgid] = self._handlers.get(msgid, ()) + (handler,)
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
            self.faults.payload = payload
            i = 0  # by index: see docs/design.md
            while i < len(handlers):
                self.faults.deliver(handlers[i], link)
                if self.faults.error is not None:
                    self.faults.count(MESSAGE, msgid)
                i += 1

    def poll(self, now=None):
        """One pass of the main loop: read every link, then run due service work. A link
        or a service that raises is a fault: the others go on.

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
        i = 0
        while i < len(self.tickers):
            faults.tick(self.tickers[i], now)
            if faults.error is not None:
                faults.count(TICK, i)
            i += 1
        faults.report(now)

    def close(self):
        for link in self.links:
            link.transport.close()
