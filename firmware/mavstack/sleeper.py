"""The main loop's sleep: until the endpoint's next work is due (Endpoint.wait_ms) or a
byte arrives on a link, whichever comes first. Where every link's transport offers a
`waitable` (a socket or file select.poll can watch) the wait ends on its bytes; on the
emulated boards qemu.wait_ms watches their UARTs; otherwise the loop sleeps at most
1 ms at a time, so that no link is left unread longer than that.
Reference: docs/core.md.
"""
from .compat import MICROPYTHON, const, sleep_ms, wait_ms

_HUNG = const(0x18)  # POLLERR | POLLHUP


class Sleeper:
    def __init__(self, links):
        self._poll = None
        self.sleep = self._short
        if wait_ms is not None:  # the emulated boards (compat.py)
            self.sleep = wait_ms
            return
        ways = [getattr(link.transport, "waitable", None) for link in links]
        if not ways or None in ways:
            return
        import select

        poll = select.poll()
        for w in ways:
            # Writable at once: the first event makes the tuple ipoll reuses, here,
            # before the heap may be locked. Then only bytes in end a wait.
            poll.register(w, select.POLLOUT)
            self._any(poll, 0)
            poll.modify(w, select.POLLIN)
        self._poll = poll
        self.sleep = self._wait

    def _short(self, ms):
        sleep_ms(ms if ms < 1 else 1)

    def _wait(self, ms):
        if ms > 0 and self._any(self._poll, ms) & _HUNG:
            sleep_ms(1)  # a hung-up device ends every wait at once: do not spin on it

    @staticmethod
    def _any(poll, ms):
        """Wait up to ms for an event -> its bits (0: none)."""
        if MICROPYTHON:
            for _obj, ev in poll.ipoll(ms):
                return ev
            return 0
        for _fd, ev in poll.poll(ms):
            return ev
        return 0
