"""The simulated vehicle with message signing: the unix board's services (files over
MAVLink FTP among them) with signing listed first, so its boot HEARTBEAT is signed too.
Unsigned until a ground station gives it a key (SETUP_SIGNING: MAVProxy's `signing
setup`, `mavctl signing`); from then on it takes only signed frames, FTP's among them.

    .venv/bin/micropython firmware/main.py --board unix_signed --link udpout:127.0.0.1:14550
"""
from unix import *  # noqa: F401,F403  (everything else as the unix board)
import unix

NAME = "unix_signed"
SERVICES = ("signing",) + unix.SERVICES
SIGNING_SETUP_LINKS = None  # a key may be given on any link: the simulator's are local
RAM_BUDGET = unix.RAM_BUDGET + 24 * 1024  # the unix board's, and signing's tables and hashing
