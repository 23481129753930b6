"""Opening the link to a vehicle, for every mavctl subcommand: a --connect spec, or
auto-connect (the one USB serial device pyserial lists, or the one vehicle heard on
UDP 14550), then the vehicle's first HEARTBEAT. Each failure is a Failure with a one-line
message saying what to check and its documented exit status (errors.py). Plug-in
modules open it with `with link.vehicle(args) as v:` (docs/mavctl.md).
"""
import contextlib
import errno
import fcntl
import os
import time

os.environ["MAVLINK20"] = "1"  # before pymavlink loads its dialect

from pymavlink import mavutil  # noqa: E402

from mavctl.errors import EXIT_NO_PORT, EXIT_PERMISSION, Failure, usage  # noqa: E402
from mavctl.keys import key_from  # noqa: E402
from mavctl.vehicle import MAV_TYPE_GCS, Vehicle  # noqa: E402

DEFAULT_BAUD = 57600
GCS_UDP_PORT = 14550  # where vehicles and radios send to a ground station by convention
CONNECT_HELP = "udpout:HOST:PORT, udpin:ADDR:PORT, tcp:HOST:PORT or serial:DEVICE[:BAUD]"


def parse_spec(spec):
    """(pymavlink target, extra options) for a --connect spec; a bare device path is serial."""
    if spec.startswith("/") or spec.startswith("COM"):
        spec = "serial:" + spec
    kind, _, rest = spec.partition(":")
    if kind == "serial":
        device, _, baud = rest.rpartition(":")
        if not baud.isdigit():
            device, baud = rest, str(DEFAULT_BAUD)
        if not device:
            raise usage("--connect serial:DEVICE:BAUD")
        return device, {"baud": int(baud)}
    if kind in ("udpout", "udpin", "udp", "tcp") and rest.rpartition(":")[2].isdigit():
        return spec, {}
    raise usage("--connect " + CONNECT_HELP)


def open_error(spec, e):
    """The Failure for an exception raised while opening spec."""
    code = getattr(e, "errno", None)
    text = str(e)
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return Failure("%s: permission denied: add yourself to the device's group (dialout, uucp)"
                       " and log in again, or check the device's mode" % spec, EXIT_PERMISSION)
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO) or "No such file" in text:
        return Failure("%s: no such port: is the board plugged in? `mavctl ports` lists them" % spec,
                       EXIT_NO_PORT)
    if code in (errno.EBUSY, errno.EAGAIN, errno.EADDRINUSE) or "lock" in text:
        return Failure("%s: port busy: another program (a ground station, mpremote, a serial "
                       "terminal) has it open" % spec, EXIT_NO_PORT)
    return Failure("cannot open %s: %s" % (spec, text), EXIT_NO_PORT)


def open_link(spec, sysid=255, compid=190):
    """A pymavlink connection for a --connect spec. A serial device is locked (flock, as
    pyserial's exclusive mode) so that two programs cannot share it unawares."""
    target, extra = parse_spec(spec)
    opts = dict(source_system=sysid, source_component=compid, dialect="common",
                autoreconnect=False, **extra)
    try:
        conn = mavutil.mavlink_connection(target, **opts)
    except Exception as e:  # serial.SerialException, OSError, socket errors
        raise open_error(spec, e)
    port = getattr(conn, "port", None)
    if "baud" in extra and hasattr(port, "fileno"):
        try:
            fcntl.flock(port.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            conn.close()
            raise open_error(spec, e)
    return conn


def usb_serial_ports():
    """Device paths of the USB serial ports pyserial lists (boards, radios, adapters)."""
    from serial.tools import list_ports
    return sorted(p.device for p in list_ports.comports() if p.vid is not None)


def heard_on_udp(port, seconds, sysid, compid):
    """(udpin connection on port, the system ids heard) if vehicles' HEARTBEATs arrive there
    within seconds (listening a beat longer after the first, to hear any other), else
    (None, ()) (also when another program holds the port)."""
    try:
        conn = open_link("udpin:0.0.0.0:%d" % port, sysid, compid)
    except Failure:
        return None, ()
    systems = set()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        msg = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
        if msg is not None and msg.type != MAV_TYPE_GCS:
            if not systems:
                deadline = min(deadline, time.monotonic() + 1.2)
            systems.add(msg.get_srcSystem())
    if systems:
        return conn, sorted(systems)
    conn.close()
    return None, ()


def autoconnect(args, listen_seconds=2.5):
    """The link when no --connect is given: the single candidate among the USB serial
    ports and the vehicles heard on UDP --udp-port (default 14550)."""
    ports = usb_serial_ports()
    udp, systems = heard_on_udp(args.udp_port, listen_seconds, args.sysid, args.compid)
    found = ["serial:%s:%d" % (p, args.baud) for p in ports]
    if args.target_system is not None and args.target_system in systems:
        systems = [args.target_system]
    elif args.target_system is not None and udp is not None:
        udp.close()
        udp, systems = None, ()
    found += ["udpin:0.0.0.0:%d (system %d)" % (args.udp_port, s) for s in systems]
    if len(found) == 1:
        if udp is not None:
            return udp
        return open_link(found[0], args.sysid, args.compid)
    if udp is not None:
        udp.close()
    if not found:
        raise Failure("no vehicle found: no USB serial device, nothing heard on UDP %d; plug the "
                      "board in or give --connect" % args.udp_port, EXIT_NO_PORT)
    raise Failure("several vehicles or ports: %s; choose one with --connect (and --target-system)"
                  % ", ".join(found), EXIT_NO_PORT)


def open_from_args(args):
    if args.connect:
        return open_link(args.connect, args.sysid, args.compid)
    return autoconnect(args)


@contextlib.contextmanager
def vehicle(args):
    """The connected Vehicle for mavctl's global options (--connect, ids, --timeout);
    the link is closed on the way out."""
    conn = open_from_args(args)
    try:
        key = link_key(args)
        if key is not None:  # a vehicle that signs: sign ours, take only what checks with it
            conn.setup_signing(key, sign_outgoing=True)
        v = Vehicle(conn, args.target_system, args.target_component)
        v.connect(args.timeout)
        yield v
    finally:
        conn.close()


def link_key(args):
    """The signing key of --key PASSPHRASE (SHA-256, as MAVProxy derives it) or
    --key-file FILE (32 bytes, 64 hex digits or a passphrase line), None without."""
    return key_from(getattr(args, "link_key", None), getattr(args, "link_key_file", None), "--key")


def add_arguments(ap):
    """mavctl's global link options."""
    ap.add_argument("--connect", metavar="LINK",
                    help=CONNECT_HELP + " (default: the one USB serial device, or a vehicle "
                    "heard on UDP 14550)")
    ap.add_argument("--baud", type=int, default=DEFAULT_BAUD,
                    help="serial speed when auto-connecting (default %d)" % DEFAULT_BAUD)
    ap.add_argument("--udp-port", type=int, default=GCS_UDP_PORT,
                    help="UDP port auto-connect listens on (default %d)" % GCS_UDP_PORT)
    ap.add_argument("--sysid", type=int, default=255, help="our system id (default 255)")
    ap.add_argument("--compid", type=int, default=190, help="our component id (default 190, a GCS)")
    ap.add_argument("--target-system", type=int, help="the vehicle's system id (default: first heard)")
    ap.add_argument("--target-component", type=int, help="the vehicle's component id")
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a HEARTBEAT")
    ap.add_argument("--key", dest="link_key", metavar="PASSPHRASE", help="MAVLink 2 signing: the vehicle's key by "
                    "passphrase (as `mavctl signing setup` and MAVProxy's `signing key` derive it)")
    ap.add_argument("--key-file", dest="link_key_file", metavar="FILE",
                    help="MAVLink 2 signing: the vehicle's key from a file")

