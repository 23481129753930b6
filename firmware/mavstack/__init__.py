"""mavstack: a MAVLink endpoint that runs on the vehicle, on MicroPython and CPython."""

VERSION = (0, 1, 0)
