"""Faults contained: an exception raised by a message or command handler, a producer, a
service's tick, the application or a transport ends that piece of work (the frame, the
tick), never the vehicle. It is counted by kind and by source, and the ground stations are
told: a STATUSTEXT at ERROR naming the source and the exception's type, at most one every
REPORT_MS (SYS_STATUS errors_count2..4 carry the counts). KeyboardInterrupt, SystemExit
and what the endpoint passes through (Reboot, Shutdown) are not faults.
The guarded calls take nothing from the heap unless something raises.
Reference: docs/reliability.md.
"""
from .compat import const, heap_open, heap_close, ticks_add, ticks_diff

MESSAGE = const(0)  # a message handler (SYS_STATUS errors_count2, with COMMAND)
COMMAND = const(1)  # a command handler (its COMMAND_ACK says FAILED)
TICK = const(2)  # a service's periodic work (errors_count3, with PRODUCER)
PRODUCER = const(3)  # a message's producer (a stream's send)
APP = const(4)  # the application's tick (errors_count4, with LINK)
LINK = const(5)  # a transport's read
REPORT_MS = const(5000)
_SOURCES = const(8)  # sources counted one by one (the oldest gives way)
_MAX = const(0xFFFF)  # counts stop there (SYS_STATUS carries 16 bits)
_KIND_NAMES = ("msg", "cmd", "tick", "producer of msg", "app", "link")


class Faults:
    def __init__(self, ep, passing):
        self.ep = ep
        self.passing = passing  # exceptions that are not faults (Reboot, Shutdown)
        self.error = None  # what the last guarded call raised, None when it returned
        self.result = None  # what run() returned
        self.payload = None  # the payload deliver() hands on
        self.counts = [0, 0, 0, 0, 0, 0]  # by kind
        self.keys = [-1] * _SOURCES  # kind << 24 | id of each source counted
        self.by_source = [0] * _SOURCES  # its count
        self._oldest = 0  # the slot a new source takes when all are in use
        self.last_kind = 0  # the last fault, for the report (attributes, not a tuple:
        self.last_ident = 0  # counting must not take from a locked heap)
        self.last_error = None
        self.owed = False  # a report is owed
        self._next = ep.now  # the next report may go then

    # --- guarded calls: one small method each, its frame within the limit -----------
    def __enter__(self):
        self.error = None

    def __exit__(self, kind, e, tb):
        if e is None:  # (a fault of a guarded call inside this one was counted there)
            self.error = None
            return False
        if not isinstance(e, Exception) or isinstance(e, self.passing):
            return False
        self.error = e
        return True

    def deliver(self, fn, link):
        """fn(link, self.payload): a message handler."""
        with self:
            fn(link, self.payload)

    def tick(self, obj, now):
        """obj.tick(now) -> what it returned (ms to its next work), None when it raised."""
        self.result = None
        with self:
            self.result = obj.tick(now)
        return self.result

    def poll(self, link):
        with self:
            link.poll()

    def run(self, fn, arg):
        """fn(arg) -> what it returned, None when it raised (self.error says)."""
        self.result = None
        with self:
            self.result = fn(arg)
        return self.result

    # --- after a guarded call raised ------------------------------------------------
    def count(self, kind, ident):
        """Count the fault in self.error against kind and source ident (a message id, a
        ticker's index, a link's index); a report is owed."""
        n = self.counts[kind] + 1
        self.counts[kind] = n if n < _MAX else _MAX
        key = kind << 24 | ident
        i = self._slot(key)
        n = self.by_source[i] + 1
        self.by_source[i] = n if n < _MAX else _MAX
        self.last_kind = kind
        self.last_ident = ident
        self.last_error = self.error
        self.owed = True

    def _slot(self, key):
        i = 0
        while i < _SOURCES:
            if self.keys[i] == key:
                return i
            i += 1
        i = self._oldest  # a new source: the slots are taken in turn
        self._oldest = (i + 1) % _SOURCES
        self.keys[i] = key
        self.by_source[i] = 0
        return i

    def source_count(self, kind, ident):
        key = kind << 24 | ident
        i = 0
        while i < _SOURCES:
            if self.keys[i] == key:
                return self.by_source[i]
            i += 1
        return 0

    def report(self, now):
        """The owed report, when the last one is REPORT_MS old (the endpoint's poll)."""
        if not self.owed or ticks_diff(now, self._next) < 0:
            return
        self.owed = False
        self._next = ticks_add(now, REPORT_MS)
        depth = heap_open()  # a rare event: the text is made on the heap
        try:
            self._tell()
        finally:
            heap_close(depth)

    def report_at(self, now):
        """ms until the owed report may go."""
        return ticks_diff(self._next, now)

    def _tell(self):
        kind = self.last_kind
        ident = self.last_ident
        if kind == TICK:
            tickers = self.ep.tickers
            where = getattr(tickers[ident], "NAME", "?") if ident < len(tickers) else "?"
            where = "tick " + where
        elif kind == APP:
            where = "application"
        else:
            where = "%s %d" % (_KIND_NAMES[kind], ident)
        name = type(self.last_error).__name__
        text = "Fault: %s: %s (%d)" % (where, name, self.source_count(kind, ident))
        print("mavstack: " + text)
        self.ep.statustext(3, text)  # MAV_SEVERITY_ERROR
