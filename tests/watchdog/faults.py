"""Faults on demand for the watchdog tests (tests/test_watchdog.py on the unix port,
tests/test_mcu_watchdog.py on the emulated M3): a board profile's application wrapped
so that it fails as its APP_FAULT parameter says, at every start, until a ground
station sets the parameter right (in safe mode, where there is no application). And
a COMMAND_LONG of MAV_CMD_USER_1 makes its handler hang, never to return, at any time:
a handler beside the commands service's, so that no message id is added (the vehicle
in its smallest heap, tests/test_mcu_watchdog.py, has no room for a new one).
"""
from mavstack.services.params import INT32

FAULT_PARAM = ("APP_FAULT", INT32, 0, 0, 2)  # 1: raise at start-up, 2: hang at start-up
MSG_COMMAND_LONG = 76
CMD_HANG = 31010  # MAV_CMD_USER_1


def faulty(application):
    """application(ep) with the faults above."""

    def make(ep):
        fault = ep.services["params"].get("APP_FAULT")
        if fault == 1:
            raise RuntimeError("APP_FAULT 1: the application fails at start-up")
        while fault == 2:  # APP_FAULT 2: it hangs at start-up
            pass
        ep.on(MSG_COMMAND_LONG, hang)
        return application(ep)

    return make


def hang(link, p):
    while p[28] | p[29] << 8 == CMD_HANG:  # COMMAND_LONG.command
        pass
