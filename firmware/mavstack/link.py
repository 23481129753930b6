"""A link: one transport with its own parser, encoder, sequence numbers, MAVLink
version and statistics. The endpoint owns several and routes them all to one vehicle.
"""
from .compat import const
from .parser import Parser
from .encoder import Encoder

_RX_CHUNK = const(512)
_RX_READS_PER_POLL = const(8)  # bounds the time one busy link can take from a poll
TX_WRAP = const(0x1FFFFFFF)  # tx_bytes wraps here: take differences as (a - b) & TX_WRAP


class Link:
    def __init__(self, endpoint, transport, index, version=0):
        self.endpoint = endpoint
        self.transport = transport
        self.index = index
        self.name = transport.name
        crc_len = endpoint.dialect.CRC_LEN
        self.rx = Parser(crc_len, self._on_frame)
        # version 0: negotiate (MAVLink 1 until the peer sends MAVLink 2).
        self.negotiate = version == 0
        self.tx = Encoder(crc_len, version or 1)
        self.txbuf = self.tx.buf
        self.bytes_per_s = transport.bytes_per_s
        self.tx_bytes = 0
        self.tx_dropped = 0
        self._rxbuf = bytearray(getattr(transport, "rx_chunk", _RX_CHUNK))

    def poll(self):
        """Read and parse whatever the transport has, without waiting."""
        for _ in range(_RX_READS_PER_POLL):
            n = self.transport.readinto(self._rxbuf)
            if not n:
                return
            self.rx.feed(self._rxbuf, n)

    def _on_frame(self, msgid, payload):
        if self.negotiate and self.rx.version == 2:
            self.tx.version = 2
            self.negotiate = False
        self.endpoint.dispatch(self, msgid, payload)

    @property
    def version(self):
        return self.tx.version

    def begin(self):
        """Payload offset in txbuf for the next frame on this link."""
        return self.tx.begin()

    def send(self, msgid, compid=-1):
        """Frame and transmit the payload packed at begin(); False if not sent."""
        ep = self.endpoint
        n = self.tx.finish(msgid, ep.sysid, ep.compid if compid < 0 else compid)
        if n == 0:
            return False
        if self.transport.write(self.txbuf, n) != n:
            self.tx_dropped += 1
            return False
        self.tx_bytes = (self.tx_bytes + n) & TX_WRAP  # a counter that stays a small int
        return True

    def send_payload(self, msgid, payload, n, compid=-1):
        """Transmit a prepacked payload[0:n] (telemetry slots keep theirs ready)."""
        self.tx.load(payload, n, msgid)
        return self.send(msgid, compid)
