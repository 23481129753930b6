"""mavctl's exit statuses and the exception that ends a run with one of them.

Every mavctl subcommand (and every plug-in module) reports a problem by raising
Failure(message, status): mavctl prints "mavctl: MESSAGE" on one line and exits with
the status. Statuses, as documented in `mavctl --help` and docs/mavctl.md:
"""

EXIT_OK = 0             # done
EXIT_REFUSED = 1        # the vehicle refused (NACK) or did not answer a request
EXIT_USAGE = 2          # bad arguments or a malformed file; nothing was sent
EXIT_NO_PORT = 3        # no device / port to talk to, or the port is busy
EXIT_PERMISSION = 4     # permission denied on the device
EXIT_NO_HEARTBEAT = 5   # the link opened but no vehicle sent a HEARTBEAT in time
EXIT_NOT_MICROPYTHON = 6  # flash: the device does not run MicroPython
EXIT_MPY_VERSION = 7    # flash: the board's .mpy version does not match the build

EXIT_STATUS_HELP = ("Exit status: 0 done, 1 refused or unanswered, 2 usage or malformed file, "
                    "3 no port or port busy, 4 permission denied, 5 no heartbeat, "
                    "6 not MicroPython, 7 .mpy version mismatch.")


class Failure(Exception):
    """Ends the run with a one-line message and an exit status."""

    def __init__(self, message, status=EXIT_REFUSED):
        Exception.__init__(self, message)
        self.status = status


def usage(message):
    return Failure(message, EXIT_USAGE)
