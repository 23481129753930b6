"""Operator control (CHANGE_OPERATOR_CONTROL #5 / _ACK #6): with a passkey, only the
ground station that took control with it may change the vehicle; services ask
ep.allows(link). The holder is one ground station (system and component id, link, UDP
address), released by it or when its own heartbeats stop. Made by the status service
(status.operator, ep.operator).
Reference: docs/services/status.md
"""
from ...compat import const, ticks_diff
from ...fields import cstr_len
from ...statustext import NOTICE

_MSG_CHANGE_OPERATOR_CONTROL_ACK = const(6)
_ACK_OK = const(0)
_ACK_WRONG_PASSKEY = const(1)
_ACK_UNSUPPORTED_ENCRYPTION = const(2)
_ACK_ALREADY_CONTROLLED = const(3)
_PASSKEY_OFFSET = const(3)
_PASSKEY_LEN = const(25)
_TAKEN = b"Operator control: GCS "
_LINK = b" link "


class Operator:
    def __init__(self, ep, passkey, timeout_ms):
        self.ep = ep
        self.passkey = passkey.encode() if isinstance(passkey, str) else passkey
        self.timeout_ms = timeout_ms
        self.sysid = 0  # ground station in control, 0: none
        self.compid = 0
        self.link = -1  # the index of the link it spoke on
        self.addr = None  # where its datagrams come from (the transport's rx_peer)
        self.seen = 0  # ticks_ms of its last heartbeat
        self._text = bytearray(_TAKEN + bytes(50 - len(_TAKEN)))  # "... GCS 255/190 link 0"

    # allows() and heartbeat() run for frames as they come: attribute compares only, the
    # address compared with == against the object kept when control was taken.
    def allows(self, link):
        return self.sysid != 0 and self._holder(link)

    def _holder(self, link):
        rx = link.rx
        if rx.sysid != self.sysid or rx.compid != self.compid or link.index != self.link:
            return False
        return getattr(link.transport, "rx_peer", None) == self.addr

    def heartbeat(self, link, now):
        if self.sysid != 0 and self._holder(link):
            self.seen = now

    def check(self, now):
        if self.sysid and ticks_diff(now, self.seen) > self.timeout_ms:
            self.sysid = 0
            self.ep.statustext(NOTICE, b"Operator control released: GCS lost")

    def request(self, link, p):
        """A CHANGE_OPERATOR_CONTROL addressed to us -> the ACK code."""
        holder = self.allows(link)
        if p[1] == 0:
            if p[2] != 0:
                return _ACK_UNSUPPORTED_ENCRYPTION
            if not self._passkey_ok(p):
                return _ACK_WRONG_PASSKEY
            if self.sysid != 0 and not holder:
                return _ACK_ALREADY_CONTROLLED
            if not holder:
                self._take(link)
            self.seen = self.ep.now
            return _ACK_OK
        if self.sysid != 0 and not holder:
            return _ACK_ALREADY_CONTROLLED
        if self.sysid:
            self.sysid = 0
            self.ep.statustext(NOTICE, b"Operator control released")
        return _ACK_OK

    def _take(self, link):
        # The holder's identity; its address kept as is (an object the transport does not
        # change), or copied if it is a buffer that could change in place.
        addr = getattr(link.transport, "rx_peer", None)
        if isinstance(addr, bytearray) or isinstance(addr, memoryview):
            addr = bytes(addr)
        self.sysid = link.rx.sysid
        self.compid = link.rx.compid
        self.link = link.index
        self.addr = addr
        # Written into a buffer made at start-up: a board may run with its heap locked.
        t = self._text
        n = _put(t, len(_TAKEN), self.sysid)
        t[n] = 0x2F  # "/"
        n = _put(t, n + 1, self.compid)
        n = _put(t, _into(t, n, _LINK), self.link)
        while n < len(t):
            t[n] = 0
            n += 1
        self.ep.statustext(NOTICE, t)

    def _passkey_ok(self, p):
        key = self.passkey
        n = len(key)
        if cstr_len(p, _PASSKEY_OFFSET, _PASSKEY_LEN) != n:
            return False
        for i in range(n):
            if p[_PASSKEY_OFFSET + i] != key[i]:
                return False
        return True


def _into(buf, at, text):
    # buf[at:] = text -> the offset after it
    for i in range(len(text)):
        buf[at + i] = text[i]
    return at + len(text)


def _put(buf, at, n):
    # The decimal digits of 0 <= n < 1000 at buf[at:] -> the offset after them
    if n >= 100:
        buf[at] = 0x30 + n // 100
        at += 1
    if n >= 10:
        buf[at] = 0x30 + n // 10 % 10
        at += 1
    buf[at] = 0x30 + n % 10
    return at + 1


def on_change_operator_control(link, p):
    """Answer a CHANGE_OPERATOR_CONTROL (target_system, control_request, version, passkey):
    the endpoint's operator decides (ep.operator; none without a passkey: granted)."""
    ep = link.endpoint
    if p[0] != ep.sysid or p[1] > 1:
        return
    ack = _ACK_OK if ep.operator is None else ep.operator.request(link, p)
    # gcs_system_id, control_request, ack: byte by byte (docs/design.md)
    off = link.begin()
    buf = link.txbuf
    buf[off] = link.rx.sysid
    buf[off + 1] = p[1]
    buf[off + 2] = ack
    link.send(_MSG_CHANGE_OPERATOR_CONTROL_ACK)
