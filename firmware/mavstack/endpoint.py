"""The endpoint: a vehicle's MAVLink identity, its links, and dispatch by message id.

Services (heartbeat, parameters, commands, missions, streams, ...) are optional
modules composed per board: each attaches to the endpoint, registers the message
ids it handles with `on()`, and, if it has periodic work, a `tick(now_ms)`.
Reference: docs/core.md.
"""
from .compat import ticks_ms
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
        self._tickers = []
        self.services = {}
        # Shared between services, filled as they attach:
        self.capabilities = 0  # MAV_PROTOCOL_CAPABILITY bits for AUTOPILOT_VERSION
        self.producers = {}  # msgid -> send(link): one message now (REQUEST_MESSAGE, streams)
        self.commands = {}  # MAV_CMD id -> handler(cmd) -> MAV_RESULT (services/commands.py)
        self.operator = None  # gate with allows(link), set by operator control

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
            self._tickers.append(service)
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
        """True when a message's target is this vehicle (0 is broadcast)."""
        return (target_system == 0 or target_system == self.sysid) and (
            target_component == 0 or target_component == self.compid
        )

    def allows(self, link):
        """May the ground station on this link change parameters, missions or arm?"""
        return self.operator is None or self.operator.allows(link)

    def statustext(self, severity, text):
        """Queue a STATUSTEXT for every link (services report refusals this way)."""
        status = self.services.get("status")
        if status is not None:
            status.statustext(severity, text)

    def dispatch(self, link, msgid, payload):
        handlers = self._handlers.get(msgid)
        if handlers is not None:
            i = 0  # by index: see docs/design.md
            while i < len(handlers):
                handlers[i](link, payload)
                i += 1

    def poll(self, now=None):
        """One pass of the main loop: read every link, then run due service work.

        Never blocks; call it from a plain loop or wrap it in asyncio.
        """
        if now is None:
            now = ticks_ms()
        self.now = now
        for link in self.links:
            link.poll()
        if self._clock is not None:
            self._clock.advance(now)
        for svc in self._tickers:
            svc.tick(now)

    def close(self):
        for link in self.links:
            link.transport.close()
