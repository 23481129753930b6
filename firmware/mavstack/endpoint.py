"""The endpoint: a vehicle's MAVLink identity, its links, and dispatch by message id.

Services (heartbeat, parameters, commands, missions, streams, ...) are optional
modules composed per board: each attaches to the endpoint, registers the message
ids it handles with `on()`, and, if it has periodic work, a `tick(now_ms)`.
"""
from .compat import ticks_ms
from .link import Link
from .uptime import Clock


class Reboot(Exception):
    """Raised out of poll() once a reboot was acknowledged; main.py restarts the board."""


class Shutdown(Exception):
    """Raised out of poll() once a shutdown was acknowledged; main.py returns."""


# Raised as made here, once: making an exception allocates, and the heap may be locked.
REBOOT = Reboot()
SHUTDOWN = Shutdown()


class Endpoint:
    def __init__(self, dialect, sysid=1, compid=1):
        self.dialect = dialect
        self.sysid = sysid
        self.compid = compid
        self.links = []
        self.now = ticks_ms()
        self.clock = Clock(self.now)  # uptime and time of day, as bytes (uptime.py)
        self._handlers = {}  # msgid -> [handler(link, payload), ...]
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

    def add(self, service, name=None):
        """Attach a service; it registers its messages in its attach(endpoint)."""
        self.services[name or service.NAME] = service
        service.attach(self)
        if hasattr(service, "tick"):
            self._tickers.append(service)
        return service

    def on(self, msgid, handler):
        """Call handler(link, payload) for every frame with this id (if the dialect has it)."""
        if msgid not in self.dialect.CRC_LEN:
            return False
        self._handlers.setdefault(msgid, []).append(handler)
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
            # By index: a for loop's iterator takes four more words of frame state, and
            # past about 11 words MicroPython puts the frame on the heap, call by call.
            i = 0
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
        self.clock.advance(now)
        for svc in self._tickers:
            svc.tick(now)

    def close(self):
        for link in self.links:
            link.transport.close()
