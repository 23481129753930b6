"""Debugging values that arrive: NAMED_VALUE_FLOAT/INT, DEBUG, DEBUG_VECT, MEMORY_VECT.

A companion computer or a ground station's script may send these to the vehicle. Each
one is handed, as it came, to the application's handler:
    ep.services["debug"].handler = handler(link, msgid, payload)
They are counted (`received`), the last one's id and payload kept (`last`,
`last_payload`). These messages carry no target: every one heard is delivered.
Outbound the same ids are telemetry slots (services/streams/telemetry.py). Delivery
allocates nothing. Reference (the payloads' layouts): docs/services/seed.md.
"""
from ..compat import const
from ..kernels import copy

MESSAGES = (249, 250, 251, 252, 254)
_LONGEST = const(36)  # MEMORY_VECT


class Debug:
    NAME = "debug"
    CLOCK = False

    def __init__(self):
        self.handler = None
        self.received = 0
        self.last = -1  # the id of the last one
        self.last_payload = bytearray(_LONGEST)

    def attach(self, ep):
        self.ep = ep
        # One bound method per id, made here: delivery makes nothing.
        for msgid in MESSAGES:
            if ep.has(msgid):
                ep.on(msgid, _Deliver(self, msgid).on)

    def deliver(self, link, msgid, payload):
        self.received += 1
        self.last = msgid
        n = len(payload) if len(payload) < _LONGEST else _LONGEST
        copy(self.last_payload, payload, 0, n)
        if self.handler is not None:
            self.handler(link, msgid, payload)


class _Deliver:
    def __init__(self, service, msgid):
        self.service = service
        self.msgid = msgid

    def on(self, link, payload):
        self.service.deliver(link, self.msgid, payload)


def create(ep):
    return ep.add(Debug())
