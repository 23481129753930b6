"""SYSID "follow": a peripheral takes its system id from the first autopilot HEARTBEAT
it hears (autopilot field not MAV_AUTOPILOT_INVALID, type not MAV_TYPE_GCS), as
peripherals on an autopilot's serial port do; until then ep.sysid is 0 and its links
send nothing (link.send). After SYSID_WAIT_MS (0: never) it falls back to SYSID_FALLBACK,
and still takes the autopilot's id when one is heard later. Made by the peripheral service.
Reference: docs/services/peripheral.md
"""
from ...compat import const, ticks_diff

_MSG_HEARTBEAT = const(0)
_MAV_TYPE_GCS = const(6)
_MAV_AUTOPILOT_INVALID = const(8)


class Follow:
    def __init__(self, ep, fallback=1, wait_ms=0):
        self.ep = ep
        self.fallback = fallback
        self.wait_ms = wait_ms
        self.source = 0  # 0 waiting, 1 the fallback, 2 the autopilot's
        self.autopilot = -1  # (sysid << 8 | compid) of the autopilot followed, -1: none yet
        self._since = ep.now
        ep.on(_MSG_HEARTBEAT, self._on_heartbeat)

    def _on_heartbeat(self, link, p):
        if self.source == 2 or p[5] == _MAV_AUTOPILOT_INVALID or p[4] == _MAV_TYPE_GCS:
            return
        sysid = link.rx.sysid
        if sysid == 0:
            return
        self.ep.sysid = sysid  # every frame from now on is stamped with it (link.send)
        self.autopilot = sysid << 8 | link.rx.compid
        self.source = 2

    def tick(self, now):
        if self.source or not self.wait_ms:
            return
        if ticks_diff(now, self._since) >= self.wait_ms:
            self.ep.sysid = self.fallback
            self.source = 1
