"""A link: one transport with its own parser, encoder, sequence numbers, MAVLink
version, statistics and byte budget. The endpoint owns several and routes them all to
one vehicle.

Every frame a link sends is paid from one token bucket filled at link.bytes_per_s, at a
rank (RANK_VITAL ... RANK_OTHER) that may spend it down to the rank's own floor; each of
the last few senders answered has an allowance of its own, so a flood is answered last,
and ground stations heard before it (GCS HEARTBEATs, operator control) keep theirs.
Reference (the ranks, send, can_send, the senders' shares): docs/core.md.
"""
from .compat import const, ticks_diff, ticks_add
from .parser import Parser
from .encoder import Encoder
from .kernels import copy

_RX_CHUNK = const(512)
_RX_READS_PER_POLL = const(8)  # bounds the time one busy link can take from a poll
TX_WRAP = const(0x1FFFFFFF)  # tx_bytes, tx_held, tx_dropped wrap here (as the parser's
# counters): take differences as (a - b) & TX_WRAP

RANK_AUTO = const(-1)
RANK_VITAL = const(0)
RANK_REPLY = const(1)
RANK_BULK = const(2)
RANK_FILL = const(3)
RANK_OTHER = const(4)
_RANK_NEW = const(5)  # (by _auto only) answers to a sender not kept, within its share
# Each rank's floor, in bytes (the credit counts thousandths): a send may take the credit
# down to it. (Bytes, not thousandths: a frozen tuple's ints from 2^13 up are long-int
# objects, and arithmetic on one allocates.)
# The gaps between the floors are what each rank keeps for the ones above it: 256 bytes
# for answers (a flood's share and another station's answers at once), the lower half of
# it for the stations kept, and a due stream frame (up to 64 bytes) goes at once while a
# list keeps the credit at its floor.
_FLOOR = (-128, 0, 256, 320, 384, 128)
_FLOOR_FILL = const(320000)  # _FLOOR[RANK_FILL] in thousandths, for forward()
_BURST_MS = const(200)  # the bucket holds 200 ms of the link ...
_MIN_CAP = const(700000)  # ... or RANK_OTHER's floor and a full MAVLink 2 frame
_UNPACED = const(5000000)  # B/s: above this a link is not budgeted (and bps * ms stays small)
_SENDERS = const(8)
_SHARE_RATE_DIV = const(16)  # a sender's allowance fills at bytes_per_s / 16 ...
_SHARE_CAP_DIV = const(8)  # ... up to bytes_per_s / 8
_SHARE_FILL_MS = const(2000)  # (so an empty one is full after this long)
_SHARE_START_DIV = const(16)  # a slot starts with a second's worth
_KEEP_MS = const(5000)  # a sender's slot is kept this long after its last GCS HEARTBEAT
_UNKNOWN = const(-1)  # _slot: the sender not looked up yet
_NO_SLOT = const(-2)  # _slot: every slot kept by others
_MSG_HEARTBEAT = const(0)
_MAV_TYPE_GCS = const(6)
_MSG_RADIO_STATUS = const(109)
_COMP_RADIO = const(68)  # MAV_COMP_ID_TELEMETRY_RADIO (SiK: system 51)
_MSG_NAMED_VALUE_INT = const(252)
_FLOW_MIN = const(5)  # radio flow control: the budget never below 5% of the medium's
_FLOW_UP = const(5)  # percentage points a report with room to spare gives back
_FLOW_NAME = b"LINK_FLOW"
_BUSY_PCT = const(80)  # a link sending this much of its budget may be given more


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
        # Radio flow control (docs/routing.md): the radio's RADIO_STATUS txbuf (% free)
        # scales the budget, self.flow percent of the medium's rate (medium_bps).
        self.medium_bps = transport.bytes_per_s
        self.flow = 100
        self.radio_reports = 0
        self._flow_on = endpoint.setting("RADIO_FLOW", True)
        self._low = endpoint.setting("RADIO_LOW_WATER", 50)
        self._high = endpoint.setting("RADIO_HIGH_WATER", 90)
        self._start = endpoint.setting("RADIO_FLOW_START", 50)
        self._flow_tx = 0
        self._flow_at = endpoint.now
        self.tx_bytes = 0
        self.tx_dropped = 0
        self.fwd_frames = 0  # frames routed here from other links (router.py)
        self._rxbuf = bytearray(getattr(transport, "rx_chunk", _RX_CHUNK))
        # A transport that wants to know which of its datagrams held a valid frame (UDP
        # servers choose their peers by it): heard(now), bound once here.
        self._heard = getattr(transport, "heard", None)
        # The budget (docs/core.md).
        self.rank = RANK_AUTO
        self.tx_low = 0
        self.tx_held = 0
        self.credit = _cap(self.bytes_per_s) if self.bytes_per_s <= _UNPACED else 0  # full
        self._last = endpoint.now
        self._in_frame = False  # a received frame is being handled
        self._slot = _UNKNOWN  # its sender's place in _who
        self._who = [0] * _SENDERS  # (sysid << 8 | compid) + 1, 0: free
        # What each may still be answered at RANK_REPLY (1/1000 B), and when it last sent
        # a GCS HEARTBEAT (its slot kept _KEEP_MS from then).
        bps = self.bytes_per_s
        start = bps // _SHARE_START_DIV * 1000 if bps <= _UNPACED else 0  # (below 2^30)
        self._allow = [start] * _SENDERS
        self._filled = [self._last] * _SENDERS  # when each allowance was last filled (_share)
        self._beat = [ticks_add(self._last, -_KEEP_MS)] * _SENDERS

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
        if self._heard is not None:
            self._heard(self.endpoint.now)
        self._in_frame = True
        self._slot = _UNKNOWN
        if msgid == _MSG_HEARTBEAT and payload[4] == _MAV_TYPE_GCS:
            self._keep()
        elif msgid == _MSG_RADIO_STATUS and self._flow_on and self.rx.compid == _COMP_RADIO:
            self._radio(payload[6])
        if self.endpoint.router is not None:
            self.endpoint.router.route(self, msgid)  # forwarded first (router.py)
        self.endpoint.dispatch(self, msgid, payload)
        self._in_frame = False
        self._slot = _UNKNOWN

    @property
    def version(self):
        return self.tx.version

    def begin(self):
        """Payload offset in txbuf for the next frame on this link."""
        return self.tx.begin()

    def send(self, msgid, compid=-1):
        """Frame and transmit the payload packed at begin(), paid from the budget at
        self.rank; False if not sent."""
        ep = self.endpoint
        if ep.sysid == 0:  # a peripheral still learning its system id (SYSID "follow")
            return False
        n = self.tx.finish(msgid, ep.sysid, ep.compid if compid < 0 else compid)
        if n == 0:
            return False
        if not self._pay(n):
            self._unsend()
            return False
        if self.transport.write(self.txbuf, n) != n:
            self._dropped(n)
            return False
        self.tx_bytes = (self.tx_bytes + n) & TX_WRAP  # a counter that stays a small int
        return True

    def send_payload(self, msgid, payload, n, compid=-1):
        """Transmit a prepacked payload[0:n] (telemetry slots keep theirs ready)."""
        self.tx.load(payload, n, msgid)
        return self.send(msgid, compid)

    def forward(self, buf, n):
        """Write a frame routed from another link, buf[0:n] as it came, paid from the
        budget at RANK_FILL (docs/routing.md); False if not written."""
        bps = self.bytes_per_s
        if bps > 0 and bps <= _UNPACED:
            if self._last != self.endpoint.now:
                self._refill()
            if self.credit - n * 1000 < _FLOOR_FILL:
                self.tx_held = (self.tx_held + 1) & TX_WRAP
                return False
            self.credit -= n * 1000
        if self.transport.write(buf, n) != n:
            self.tx_dropped = (self.tx_dropped + 1) & TX_WRAP
            return False
        self.tx_bytes = (self.tx_bytes + n) & TX_WRAP
        self.tx_low = (self.tx_low + n) & TX_WRAP  # yields to streams, as lists do
        self.fwd_frames = (self.fwd_frames + 1) & TX_WRAP
        return True

    # --- radio flow control (as ArduPilot's handle_radio_status) ---------------------
    def _radio(self, txbuf):
        """A RADIO_STATUS on this link: its radio's transmit buffer is txbuf % free. The
        first one starts the budget at RADIO_FLOW_START %; then below the low-water mark
        it steps down (by a half below half of it, else a quarter), and above the
        high-water mark, if the link used most of it since the last report, back up;
        streams fit to it within a second (docs/routing.md)."""
        bps = self.medium_bps
        if bps <= 0 or bps > _UNPACED:
            return
        was = flow = self.flow
        if self.radio_reports == 0:
            flow = self._start
        elif txbuf < self._low // 2:
            flow = flow // 2
        elif txbuf < self._low:
            flow = flow * 3 // 4
        elif txbuf > self._high and self._busy():
            flow += _FLOW_UP
        self.radio_reports = (self.radio_reports + 1) & TX_WRAP
        self._flow_tx = self.tx_bytes
        self._flow_at = self.endpoint.now
        self.flow = _FLOW_MIN if flow < _FLOW_MIN else 100 if flow > 100 else flow
        self.bytes_per_s = bps * self.flow // 100 or 1
        if self.flow < 100 or was < 100:
            self._report_flow()

    def _busy(self):
        """Did the link send at least _BUSY_PCT % of its budget since the last report?"""
        dt = ticks_diff(self.endpoint.now, self._flow_at) // 10  # centiseconds
        if dt <= 0:
            return False
        # Bytes a centisecond against the budget's (no int reaches 2^30).
        return ((self.tx_bytes - self._flow_tx) & TX_WRAP) // dt >= self.bytes_per_s * _BUSY_PCT // 10000

    def _report_flow(self):
        """NAMED_VALUE_INT LINK_FLOW = the scale in percent, on this link (mavctl watch)."""
        ep = self.endpoint
        if not ep.has(_MSG_NAMED_VALUE_INT):
            return
        off = self.tx.clear(18)
        if ep._clock is not None:
            ep._clock.stamp_ms(self.txbuf, off)
        self.txbuf[off + 4] = self.flow
        copy(self.txbuf, _FLOW_NAME, off + 8, 9)
        self.rank = RANK_BULK
        self.send(_MSG_NAMED_VALUE_INT)
        self.rank = RANK_AUTO

    # --- the budget (small functions: see docs/design.md) -----------------------------
    def can_send(self, nbytes, rank):
        """Would a frame of nbytes go at rank (RANK_AUTO: as send would rank it) now?"""
        bps = self.bytes_per_s
        if bps <= 0 or bps > _UNPACED:
            return True
        self._refill()
        if rank < 0:
            rank = self._auto(nbytes)
        return self.credit - nbytes * 1000 >= _FLOOR[rank] * 1000

    def ready_in(self, nbytes, rank):
        """ms until a frame of nbytes could go at rank (1 at least: a sender that waits
        for the budget sleeps until then, not a pass at a time)."""
        bps = self.bytes_per_s
        if bps <= 0 or bps > _UNPACED:
            return 1
        self._refill()
        need = (_FLOOR[rank] + nbytes) * 1000 - self.credit
        return (need + bps - 1) // bps if need > 0 else 1

    def _pay(self, n):
        """Pay for the frame of n bytes at self.rank (RANK_AUTO: by its sender) -> paid;
        False: the budget holds it back (counted). One call a send: refill, rank, the
        bucket, the low ranks' count and the sender's allowance."""
        rank = self.rank
        if rank < 0:
            rank = self._auto(n)
        bps = self.bytes_per_s
        if 0 < bps <= _UNPACED:
            self._refill()
            if self.credit - n * 1000 < _FLOOR[rank] * 1000:
                self.tx_held = (self.tx_held + 1) & TX_WRAP
                return False
            self.credit -= n * 1000
        if rank == RANK_FILL or rank == RANK_OTHER:
            self.tx_low = (self.tx_low + n) & TX_WRAP
        if self._slot >= 0:
            if self._filled[self._slot] != self.endpoint.now:  # (_auto has filled it)
                self._share(self._slot)
            n = self._allow[self._slot] - n * 1000
            self._allow[self._slot] = n if n > 0 else 0
        return True

    def _dropped(self, n):
        # The transport did not take the frame it was paid for: the bucket has it back.
        self.tx_dropped = (self.tx_dropped + 1) & TX_WRAP
        if 0 < self.bytes_per_s <= _UNPACED:
            self.credit += n * 1000

    def _unsend(self):
        # The frame was sealed but does not go: its sequence number is given back, so
        # the peer counts no loss.
        tx = self.tx
        tx.seq = (tx.seq - 1) & 0xFF
        tx.frames -= 1

    def _refill(self):
        now = self.endpoint.now
        dt = ticks_diff(now, self._last)
        if dt == 0:
            return
        self._last = now
        if dt > 0:
            bps = self.bytes_per_s
            cap = _cap(bps)
            if dt > cap // bps + 1:
                dt = cap // bps + 1  # (bps * dt stays below 2^30)
            credit = self.credit + bps * dt
            self.credit = credit if credit < cap else cap

    def _share(self, i):
        """Sender slot i's allowance, filled at bytes_per_s / 16 up to bytes_per_s / 8 for
        the time since it was last looked at -> it. (Filled when looked at, not on every
        refill: a send pays for its own sender's slot alone.)"""
        allow = self._allow
        dt = ticks_diff(self.endpoint.now, self._filled[i])
        if dt > 0:
            self._filled[i] = self.endpoint.now
            bps = self.bytes_per_s
            if 0 < bps <= _UNPACED:  # (a step below 2^30: bps / 16 * 2000 ms at most)
                cap = bps // _SHARE_CAP_DIV * 1000
                a = allow[i] + bps // _SHARE_RATE_DIV * dt if dt < _SHARE_FILL_MS else cap
                allow[i] = a if a < cap else cap
        return allow[i]

    def _auto(self, n):
        """The rank of a send of n bytes that did not say: by the sender of the frame
        being handled (docs/core.md, a sender's share)."""
        if not self._in_frame:
            return RANK_REPLY
        op = self.endpoint.operator
        if op is not None and op.sysid != 0:  # a ground station in control: it alone
            return RANK_REPLY if op.allows(self) else RANK_OTHER
        if self._slot == _UNKNOWN:
            self._slot = self._sender()
        if self._slot < 0 or self._share(self._slot) < n * 1000:
            return RANK_OTHER
        n = ticks_diff(self.endpoint.now, self._beat[self._slot])  # (_kept, inline; n reused)
        return RANK_REPLY if 0 <= n < _KEEP_MS else _RANK_NEW

    def sender_kept(self):
        """Is the frame being handled from a sender whose share is kept (the ground
        station in control, or one heard sending GCS HEARTBEATs lately)? Outside a
        frame (timers): True."""
        return self._auto(0) == RANK_REPLY

    def _kept(self, i):
        d = ticks_diff(self.endpoint.now, self._beat[i])
        return 0 <= d < _KEEP_MS

    def _keep(self):
        """A GCS HEARTBEAT: its sender's slot is kept from now (a newcomer takes one)."""
        self._slot = self._sender()
        if self._slot >= 0:
            self._beat[self._slot] = self.endpoint.now

    def _sender(self):
        """The slot of the current sender's allowance -> its index, or _NO_SLOT. A
        newcomer takes over a free slot, else of those not kept the one with the most
        allowance left (the quietest sender's), with what allowance it has left."""
        key = (self.rx.sysid << 8 | self.rx.compid) + 1
        i = 0
        while i < _SENDERS:
            if self._who[i] == key:
                return i
            i += 1
        best = _NO_SLOT
        i = 0
        while i < _SENDERS and self._who[i] != 0:
            if (best < 0 or self._share(i) > self._share(best)) and not self._kept(i):
                best = i
            i += 1
        if i < _SENDERS:
            best = i  # a free one
        if best >= 0:
            self._who[best] = key
        return best


def _cap(bps):
    cap = bps * _BURST_MS
    return cap if cap > _MIN_CAP else _MIN_CAP
