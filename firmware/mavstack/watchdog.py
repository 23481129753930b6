"""The crash-loop guard of a board with a watchdog.

main.py starts the board's watchdog (its profile's watchdog(ms), WATCHDOG_MS) and feeds
it on every pass of the poll loop. A board its watchdog restarts could restart for
ever: the guard counts the starts that ended neither cleanly (an acknowledged reboot or
shutdown, a Ctrl-C) nor after a clean minute (CLEAN_RUN_MS), in a small sealed file.
After 3 of them in a row the vehicle starts in safe mode: the services of status,
params and commands the board lists, no application, and a STATUSTEXT a second saying
so until its clean minute, which clears the count.
Reference: docs/reliability.md.
"""
from .compat import const, ticks_add, ticks_diff
from .storage import save_sealed, sealed

_SAFE_AFTER = const(3)
_TEXT_MS = const(1000)  # as often as HEARTBEAT
_CRITICAL = const(2)  # MAV_SEVERITY_CRITICAL
_MAX = const(255)


class Guard:
    """A service main.py adds before the board's: attach() counts this start (file
    "boot": the count, sealed) and cuts `services` down in safe mode; tick() tells of it
    and clears the count after the clean minute; stop() clears it at a clean end."""

    NAME = "boot"
    CLOCK = False

    def __init__(self, services):
        self.services = services  # the board's SERVICES, or those of safe mode
        self.safe = False
        self.text = None  # what STATUSTEXT says in safe mode
        self.record = bytearray(3)
        self.ep = None
        self._clean_at = 0
        self._next_text = 0
        self._done = False

    def attach(self, ep):
        self.ep = ep
        self._clean_at = ticks_add(ep.now, ep.setting("CLEAN_RUN_MS", 60000))
        self._next_text = ep.now
        n = 0  # no file yet: no start has counted
        try:
            f = ep.storage.open("boot")
            if f.readinto(self.record) == 3 and sealed(self.record, 3):
                n = self.record[0]
            f.close()
        except OSError:
            pass
        self._write(n + 1 if n < _MAX else n)  # this start counts until it ends cleanly
        if n >= _SAFE_AFTER:
            self.safe = True
            self.services = tuple(s for s in self.services if s in ("status", "params", "commands"))
            self.text = ("Safe mode after %d resets: %s" % (n, ",".join(self.services))).encode()
            print("mavstack: " + self.text.decode())

    def tick(self, now):
        if self._done:
            return 1000
        if self.safe and ticks_diff(now, self._next_text) >= 0:
            self._next_text = ticks_add(now, _TEXT_MS)
            self.ep.statustext(_CRITICAL, self.text)
        if ticks_diff(now, self._clean_at) >= 0:
            self.stop()
        ms = ticks_diff(self._clean_at, now)
        return ms if not self.safe or ticks_diff(self._next_text, now) > ms else ticks_diff(self._next_text, now)

    def stop(self):
        """A clean minute, or a clean end (main.py): the count starts again."""
        if not self._done:
            self._done = True
            self._write(0)

    def _write(self, count):
        self.record[0] = count
        save_sealed(self.ep.storage, "boot", self.record)
