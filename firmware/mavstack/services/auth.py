"""AUTH_KEY (#7): the key that identifies a system, only ever over a signed link.

The seed asks for an encrypted channel; here it is a signed MAVLink 2 link
(services/signing.py). The vehicle's own key (board setting AUTH_KEY) is sent on request
or by a stream only on a link that signs what it sends (a request over an unsigned link
is DENIED); an AUTH_KEY that arrives is taken only in a signed frame, kept as that
link's (`keys`, `known` against AUTH_KEYS_ACCEPTED) and handed to on_key(link, payload).
Without signing on, no AUTH_KEY goes out and none is taken. Nothing is allocated per
message: the keys live in buffers made at start-up.
Reference: docs/services/seed.md.
"""
from ..compat import const
from ..kernels import copy
from ..statustext import WARNING

_MSG_AUTH_KEY = const(7)
_CMD_REQUEST_MESSAGE = const(512)
_DENIED = const(2)
_KEY = const(32)
_INFO = const(6)  # MAV_SEVERITY_INFO


def link_signed(link):
    """Does this link sign what it sends (signing on, MAVLink 2)?"""
    return link.tx.sign is not None and link.tx.version == 2


def frame_signed(link):
    """Was the frame being handled on this link signed (and its signature checked)?"""
    return link.tx.sign is not None and link.rx.signed


class Auth:
    NAME = "auth"
    CLOCK = False

    def __init__(self, key=None, accepted=None, links=4):
        self.key = bytearray(_KEY)
        self.has_key = bool(key)
        if key:
            key = key.encode() if isinstance(key, str) else key
            copy(self.key, key, 0, min(len(key), _KEY))
        self.accepted = tuple(a.encode() if isinstance(a, str) else a for a in accepted) if accepted else None
        self.keys = [bytearray(_KEY) for _ in range(links)]
        self.known = [False] * links
        self.on_key = None  # handler(link, payload), the application's
        self.refused = 0
        self._request = None

    def attach(self, ep):
        self.ep = ep
        while len(self.keys) < len(ep.links):
            self.keys.append(bytearray(_KEY))
            self.known.append(False)
        if not ep.has(_MSG_AUTH_KEY):
            return
        ep.on(_MSG_AUTH_KEY, self._on_key)
        if self.has_key:
            ep.producers[_MSG_AUTH_KEY] = self.send
            # REQUEST_MESSAGE for AUTH_KEY on an unsigned link: DENIED, not ACCEPTED
            # with nothing following.
            self._request = ep.commands.get(_CMD_REQUEST_MESSAGE)
            if self._request is not None:
                ep.commands[_CMD_REQUEST_MESSAGE] = self._request_message

    def send(self, link):
        if not link_signed(link):
            return False
        off = link.begin()
        copy(link.txbuf, self.key, off, _KEY)
        return link.send(_MSG_AUTH_KEY)

    def _request_message(self, cmd):
        if cmd.finite(1) and cmd.int(1) == _MSG_AUTH_KEY and not link_signed(cmd.link):
            self.ep.statustext(WARNING, b"AUTH_KEY: only over a signed link")
            return _DENIED
        return self._request(cmd)

    def _on_key(self, link, p):
        if not frame_signed(link):
            self.refused += 1
            self.ep.statustext(WARNING, b"AUTH_KEY refused: link not signed")
            return
        i = link.index
        copy(self.keys[i], p, 0, _KEY)
        self.known[i] = self._accepts(self.keys[i])
        self.ep.statustext(_INFO, b"AUTH_KEY accepted" if self.known[i] else b"AUTH_KEY not known")
        if self.on_key is not None:
            self.on_key(link, p)

    def _accepts(self, key):
        if self.accepted is None:
            return True
        for a in self.accepted:
            if _same(key, a):
                return True
        return False


def _same(key, text):
    # The key as a char[32]: text, then zeros.
    i = 0
    while i < _KEY:
        if key[i] != (text[i] if i < len(text) else 0):
            return False
        i += 1
    return True


def create(ep):
    board = getattr(ep, "board", None)
    return ep.add(Auth(ep.setting("AUTH_KEY", None), getattr(board, "AUTH_KEYS_ACCEPTED", None),
                       len(ep.links)))
