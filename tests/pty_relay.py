"""A lossy serial link made of two ptys: the vehicle opens one (`--link serial:DEV:BAUD`), the
ground station the other, and a thread between their masters drops, duplicates and holds
back whole MAVLink frames, as relay.LossyRelay does for UDP datagrams.

    r = PtyRelay(rate=0.2, seed=1)
    r.vehicle_dev, r.gcs_dev        the two slave devices
    r.stats                         frames, dropped, duplicated, delayed
    r.close()

PtyRelay(rate=0.0, far_dev=PATH, record=True) is a tap on a serial line: its far side is
an existing device (an emulated board's UART pty) instead of a second pty, and r.frames
holds the whole frames that passed each way (r.frames[TO_GCS]: to the far side).

Bytes between frames (noise, a frame cut short) pass through as they came.
"""
import heapq
import os
import random
import select
import threading
import time
import tty

TO_VEHICLE = 0
TO_GCS = 1


def _open_pty():
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def split_frames(buf):
    """-> (whole frames and stray bytes in order, the unfinished rest of buf)."""
    out = []
    i = 0
    while i < len(buf):
        stx = buf[i]
        if stx not in (0xFD, 0xFE):
            j = i
            while j < len(buf) and buf[j] not in (0xFD, 0xFE):
                j += 1
            out.append(bytes(buf[i:j]))
            i = j
            continue
        if i + 3 > len(buf):
            break
        if stx == 0xFE:
            n = 8 + buf[i + 1]
        else:
            n = 12 + buf[i + 1] + (13 if buf[i + 2] & 1 else 0)
        if i + n > len(buf):
            break
        out.append(bytes(buf[i:i + n]))
        i += n
    return out, buf[i:]


class PtyRelay:
    def __init__(self, rate=0.2, delay=(0.001, 0.02), seed=1, far_dev=None, record=False):
        self.rng = random.Random(seed)
        self.rate = rate
        self.delay = delay
        self.stats = {"frames": 0, "dropped": 0, "duplicated": 0, "delayed": 0}
        self._veh_master, self._veh_slave, self.vehicle_dev = _open_pty()
        if far_dev is None:
            self._gcs_master, self._gcs_slave, self.gcs_dev = _open_pty()
        else:
            fd = os.open(far_dev, os.O_RDWR | os.O_NOCTTY)
            tty.setraw(fd)
            os.set_blocking(fd, False)
            self._gcs_master, self._gcs_slave, self.gcs_dev = fd, None, far_dev
        self.frames = {TO_VEHICLE: [], TO_GCS: []} if record else None
        self._pending = {TO_VEHICLE: b"", TO_GCS: b""}
        self._later = []
        self._n = 0
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _write(self, fd, data):
        try:
            os.write(fd, data)
        except OSError:
            pass  # the other side's buffer is full: lost, as on a real serial line

    def _forward(self, way, data):
        fd = self._veh_master if way == TO_VEHICLE else self._gcs_master
        frames, self._pending[way] = split_frames(self._pending[way] + data)
        for f in frames:
            if f[0] not in (0xFD, 0xFE):
                self._write(fd, f)
                continue
            self.stats["frames"] += 1
            if self.frames is not None:
                self.frames[way].append(f)
            if self.rng.random() < self.rate:
                what = self.rng.randrange(3)
                if what == 0:
                    self.stats["dropped"] += 1
                    continue
                if what == 1:
                    self.stats["duplicated"] += 1
                    self._write(fd, f)
                else:
                    self.stats["delayed"] += 1
                    self._n += 1
                    heapq.heappush(self._later, (time.time() + self.rng.uniform(*self.delay), self._n, fd, f))
                    continue
            self._write(fd, f)

    def _run(self):
        fds = [self._veh_master, self._gcs_master]
        while not self._stop:
            wait = 0.02
            if self._later:
                wait = max(0.0, min(wait, self._later[0][0] - time.time()))
            try:
                ready, _, _ = select.select(fds, [], [], wait)
            except (OSError, ValueError):
                return
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                self._forward(TO_GCS if fd == self._veh_master else TO_VEHICLE, data)
            now = time.time()
            while self._later and self._later[0][0] <= now:
                _, _, fd, f = heapq.heappop(self._later)
                self._write(fd, f)

    def close(self):
        self._stop = True
        self._thread.join(2)
        for fd in (self._veh_master, self._veh_slave, self._gcs_master, self._gcs_slave):
            if fd is None:
                continue
            try:
                os.close(fd)
            except OSError:
                pass
