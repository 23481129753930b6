"""What the two emulated boards (qemu_m3, qemu_m0) share: the full service set, the
unix vehicle's 100 parameters (a block read in place), storage in a RAM region outside
the GC heap, the heap locked once the vehicle is up, and a stand-in application.

The application is a vehicle standing still on the ground with working sensors: it
writes ATTITUDE, GLOBAL_POSITION_INT, GPS_RAW_INT and VFR_HUD slots from values made
once, so its ticks allocate nothing, as a real board's sensor code must not. On qemu_m3,
whose REPL keeps UART 0, it also stops the vehicle on a Ctrl-C there, as a port's UART
interrupt would (the qemu port has none): that is how `mavctl flash` gets the REPL back.
"""
from mavstack.compat import ticks_add, ticks_diff, to_grid

DIALECT = "common"
SYSID = 1
COMPID = 1
MAV_TYPE = 10  # MAV_TYPE_GROUND_ROVER
MAV_AUTOPILOT = 0
SERVICES = ("status", "params", "commands", "missions", "streams", "signing")
BAUD = 115200  # what the link budget assumes; the emulated UART is as fast as its pty
MISSION_CAPACITY = 500
FENCE_CAPACITY = 50
RALLY_CAPACITY = 10
OPERATOR_PASSKEY = None
GCS_TIMEOUT_MS = 5000
HEAP_LOCK = True  # main.py locks the heap once the vehicle is built: a MemoryError is a bug
PARAM_ENCODING = "bytewise"
PARAM_AUTOSAVE_MS = 0  # RAM storage: saved on PREFLIGHT_STORAGE only
PARAM_SYSID = "MAV_SYS_ID"
DEFAULT_STREAMS = (  # ten streams
    (1, 1),  # SYS_STATUS
    (42, 1),  # MISSION_CURRENT
    (2, 1),  # SYSTEM_TIME
    (24, 1),  # GPS_RAW_INT
    (30, 4),  # ATTITUDE
    (33, 2),  # GLOBAL_POSITION_INT
    (74, 2),  # VFR_HUD
    (147, 0.5),  # BATTERY_STATUS
    (245, 0.5),  # EXTENDED_SYS_STATE
    (242, 0.2),  # HOME_POSITION
)
# Telemetry slots for what the application writes and the default streams send
# (GPS_RAW_INT, ATTITUDE, GLOBAL_POSITION_INT, VFR_HUD, BATTERY_STATUS, EXTENDED_SYS_STATE):
# the other writers write nowhere.
TELEMETRY = (24, 30, 33, 74, 147, 245)

# The unix vehicle's table with a uint32 BRD_SERIAL_NUM (qemu_params.py), as one block
# read in place: frozen, it stays in flash.
from qemu_params_block import PARAMS  # noqa: E402


_SENSOR_MS = 250  # StandingVehicle's sensors: how often it writes its slots
HEAP = [0, 0]  # heap in use and free (bytes) when the vehicle was shut down (bench_mcu.py)


def shutdown():
    """PREFLIGHT_REBOOT_SHUTDOWN 2: main.py returns to the REPL; the heap figures of the
    vehicle as it ran are kept here, for the REPL to read: what it holds, collected first
    (rare events open the locked heap and leave garbage behind)."""
    import gc
    import micropython

    micropython.heap_lock()
    depth = micropython.heap_unlock()  # the lock depth (compat.heap_open, without importing)
    n = depth
    while n:
        micropython.heap_unlock()
        n -= 1
    gc.collect()
    HEAP[0] = gc.mem_alloc()
    HEAP[1] = gc.mem_free()
    while depth:
        micropython.heap_lock()
        depth -= 1


def storage(address, size):
    """Files in the RAM region outside the GC heap (in a bytearray when these profiles
    run on the unix port, to try them there)."""
    import sys
    from mavstack.storage_ram import RamStorage

    if sys.platform != "qemu":
        return RamStorage(bytearray(size))
    import uctypes

    return RamStorage(uctypes.bytearray_at(address, size))


def transports():
    from mavstack.qemu import UartTransport

    return [UartTransport(BAUD)]


class StandingVehicle:
    """On the ground at the home position, level, heading north, sensors healthy."""

    LAT = 473977420  # 1e7 degrees
    LON = 85455940
    ALT_MM = 488000

    def __init__(self, ep):
        self.tm = getattr(ep, "telemetry", None)
        status = ep.services.get("status")
        if status is not None:
            status.set_home(self.LAT, self.LON, self.ALT_MM)
            status.set_sensors(0x3F, 0x3F, 0x3F)
            status.set_battery(12600, 0, 100)
        self._next = ep.now
        self._zero = 0.0
        self._interrupt = KeyboardInterrupt()  # made once: raised with the heap locked
        self._repl_uart = _repl_uart_m3()

    def tick(self, now):
        tm = self.tm
        if tm is None:
            return 1000
        if ticks_diff(now, self._next) < 0:
            return ticks_diff(self._next, now)
        # 4 Hz, the fastest default stream: the slots are sent at the rates asked for,
        # faster ones with the last values written (docs/boards.md).
        self._next = ticks_add(now, to_grid(now, _SENSOR_MS))  # with the streams' 4 Hz
        if self._repl_uart and _ctrl_c():
            raise self._interrupt
        self._write(tm)
        return ticks_diff(self._next, now)

    def _write(self, tm):
        # Apart from tick: its calls of many arguments make a frame too large for the C
        # stack (docs/design.md), which every pass would pay for, not only the writes.
        z = self._zero
        tm.attitude(z, z, z, z, z, z)
        tm.global_position(self.LAT, self.LON, self.ALT_MM, 0, 0, 0, 0, 0)
        tm.gps_raw(3, self.LAT, self.LON, self.ALT_MM, 100, 100, 0, 0, 12)
        tm.vfr_hud(z, z, 0, 0, z, z)


_mem32 = None


def _repl_uart_m3():
    global _mem32
    import sys

    if sys.platform != "qemu":
        return False
    from machine import mem32
    from mavstack.qemu import MODEL

    _mem32 = mem32
    return MODEL == "m3"


def _ctrl_c():
    """A Ctrl-C in CMSDK UART 0's receive register (the REPL's, on the MPS2 board); any
    other byte there is dropped, as the REPL is not reading while the vehicle runs."""
    return _mem32[0x40004004] & 2 and _mem32[0x40004000] == 3  # STATE: RX full; DATA


def application(ep):
    return StandingVehicle(ep)
