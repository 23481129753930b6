"""Telemetry logs (.tlog) as MAVProxy and QGroundControl write them: each MAVLink frame
as it went over the link, preceded by the time it was seen, 8 bytes big-endian, in
microseconds since 1970. pymavlink's mavlogdump and mavutil read them back.

    with TlogWriter(path) as log:
        log.attach(conn)            # frames received on a pymavlink connection, and sent
"""
import struct
import time

from mavctl.errors import Failure, usage

FLUSH_S = 1.0  # a crash loses at most this much of the log


class TlogWriter:
    def __init__(self, path):
        try:
            self.file = open(path, "wb")
        except OSError as e:
            raise usage("--tlog %s: %s" % (path, e.strerror))
        self.path = path
        self.frames = 0
        self._flushed = time.monotonic()
        self._conn = None

    def write(self, frame, when=None):
        """One frame (its bytes as on the wire), stamped now unless when (s since 1970)."""
        usec = int((time.time() if when is None else when) * 1e6)
        try:
            self.file.write(struct.pack(">Q", usec))
            self.file.write(bytes(frame))
        except OSError as e:
            raise Failure("--tlog %s: %s" % (self.path, e.strerror))
        self.frames += 1
        now = time.monotonic()
        if now - self._flushed >= FLUSH_S:
            self._flushed = now
            self.file.flush()

    def attach(self, conn):
        """Log every frame conn parses (whoever sent it) and every frame we send on it."""
        self._conn = conn
        mav = conn.mav
        previous = mav.callback

        def received(msg, *args, **kw):
            if msg.get_type() != "BAD_DATA":
                self.write(msg.get_msgbuf())
            if previous is not None:
                previous(msg, *args, **kw)

        mav.set_callback(received)
        mav.set_send_callback(lambda msg: self.write(msg.get_msgbuf()))

    def close(self):
        if self._conn is not None:
            self._conn.mav.set_send_callback(None)
            self._conn = None
        if not self.file.closed:
            self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
