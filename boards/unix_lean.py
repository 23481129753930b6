"""The unix vehicle cut down to what a small board runs: status, commands and missions,
no parameter table, telemetry streams or simulator. Used to prove that a 500-item
mission fits a board with a few tens of kilobytes of RAM (tests/test_missions_mpy.py
runs it with `-X heapsize=64K` from .mpy files).

    .venv/bin/micropython -X heapsize=64K firmware/main.py --board unix_lean --link udpin:127.0.0.1:14551
"""
NAME = "unix_lean"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 2  # MAV_TYPE_QUADROTOR
MAV_AUTOPILOT = 0  # MAV_AUTOPILOT_GENERIC
SERVICES = ("status", "commands", "missions")
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
LINKS = ("udpin:127.0.0.1:14551",)
UDP_BYTES_PER_S = 200000
MISSION_CAPACITY = 500
FENCE_CAPACITY = 100
RALLY_CAPACITY = 20
OPERATOR_PASSKEY = None
GCS_TIMEOUT_MS = 5000


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]
