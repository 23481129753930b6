"""The simulated vehicle: MicroPython's unix port, UDP (or pty) links, files on disk.

    .venv/bin/micropython firmware/main.py --board unix --link udpout:127.0.0.1:14550
"""
NAME = "unix"
DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 2  # MAV_TYPE_QUADROTOR
MAV_AUTOPILOT = 0  # MAV_AUTOPILOT_GENERIC
SERVICES = ("status", "params", "commands", "missions", "streams")
STORAGE = __file__.rsplit("/", 2)[0] + "/storage"
LINKS = ("udpout:127.0.0.1:14550",)
UDP_BYTES_PER_S = 200000
MISSION_CAPACITY = 500
FENCE_CAPACITY = 100
RALLY_CAPACITY = 20
OPERATOR_PASSKEY = None  # a string makes CHANGE_OPERATOR_CONTROL required to take control
GCS_TIMEOUT_MS = 5000
RAM_BUDGET = 256 * 1024


def transports():
    from mavstack.transport import open_transport

    return [open_transport(spec, UDP_BYTES_PER_S) for spec in LINKS]


def application(endpoint):
    from simulator import Simulator

    return Simulator(endpoint)
