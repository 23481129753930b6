"""`mavctl signing setup PASSPHRASE|--key-file F` and `mavctl signing clear`: give the
vehicle a MAVLink 2 signing key with SETUP_SIGNING, or take it away (an all-zero key).
The key is derived as MAVProxy derives it (keys.py). The vehicle answers with a
STATUSTEXT alone, so success is proven by what follows: frames from the vehicle that
check with the new key (setup), or unsigned ones (clear). Reference: docs/mavctl.md.
"""
import sys
import time

from mavctl.args import group
from mavctl.errors import EXIT_OK, EXIT_REFUSED, Failure, usage
from mavctl.keys import key_from

EPOCH_2015 = 1420070400  # signing timestamps count 10 us units from 2015-01-01 UTC
TRIES = 3
WAIT_S = 1.5  # per try: the vehicle answers at once, a radio may lose a frame
LINK_ID = 0


def timestamp_now():
    return int((max(time.time(), EPOCH_2015) - EPOCH_2015) * 100000)


def frame_signed(msg):
    buf = msg.get_msgbuf()
    return len(buf) > 2 and buf[0] == 0xFD and bool(buf[2] & 1)


class Signer:
    """Our side's signing on the pymavlink connection: which key (None: unsigned) signs
    what we send, and which key checks what we receive."""

    def __init__(self, conn):
        self.conn = conn
        conn.disable_signing()
        conn.mav.signing.timestamp = timestamp_now()

    def use(self, key):
        s = self.conn.mav.signing
        if key is None:
            s.secret_key = None
            s.sign_outgoing = False
        else:
            s.secret_key = key
            s.sign_outgoing = True
            s.link_id = LINK_ID
            s.timestamp = max(s.timestamp, timestamp_now())

    def send(self, msg, key):
        """msg signed with key (None: unsigned); receiving goes on with the key set before."""
        s = self.conn.mav.signing
        keep = s.secret_key, s.sign_outgoing
        self.use(key)
        self.conn.mav.send(msg)
        s.secret_key, s.sign_outgoing = keep


def setup_signing(v, new_key, current_key):
    """SETUP_SIGNING with new_key (all zeros: off), sent signed with current_key, until the
    vehicle's frames show it took it -> the STATUSTEXTs it sent meanwhile."""
    off = not any(new_key)
    signer = Signer(v.conn)
    msg = v.mav.setup_signing_encode(v.target_system, v.target_component, new_key, timestamp_now())
    heard = []
    v.echo_statustext = False
    for _ in range(TRIES):
        signer.send(msg, current_key)
        # From now on only what the vehicle signs with the new key (or, turning signing
        # off, what it sends unsigned) gets through: the proof it took the request.
        signer.use(None if off else new_key)
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            got = v.recv(None, deadline - time.monotonic())
            if got is None:
                break
            if got.get_type() == "STATUSTEXT":
                heard.append(got.text)
            if not (off and frame_signed(got)):
                # A little longer for its "Signing on/off", sent with the change.
                late = v.recv(("STATUSTEXT",), 0.5, lambda m: "Signing" in m.text)
                if late is not None:
                    heard.append(late.text)
                return heard
    return None


def check_vehicle(v, current_key):
    """Refuse early when the vehicle signs and no key for it was given."""
    hb = getattr(v, "heartbeat_msg", None) or v.recv(("HEARTBEAT",), 3.0)
    if hb is not None and frame_signed(hb) and current_key is None:
        raise usage("the vehicle signs its frames: give the key it has with --current "
                    "PASSPHRASE or --current-key-file FILE")


def refused(what):
    return Failure("the vehicle did not take the %s: it takes SETUP_SIGNING only on the links its "
                   "board trusts for it (SIGNING_SETUP_LINKS: try the USB cable rather than the "
                   "radio), signed with the key it has (--current), and only with the signing "
                   "service on" % what, EXIT_REFUSED)


def run_setup(v, args):
    if args.passphrase is not None and len(args.passphrase.split()) != 1:
        print("mavctl: note: MAVProxy's `signing key` takes one word; given this passphrase it "
              "would derive another key", file=sys.stderr)
    check_vehicle(v, args.current_key)
    heard = setup_signing(v, args.key, args.current_key)
    if heard is None:
        raise refused("key")
    print("signing on: key %s... set; frames from the vehicle check with it" % args.key[:4].hex())
    if not any("Signing on" in t for t in heard):
        print("mavctl: the vehicle's \"Signing on\" was not heard (lost on the link?)", file=sys.stderr)
    return EXIT_OK


def run_clear(v, args):
    check_vehicle(v, args.current_key)
    heard = setup_signing(v, bytes(32), args.current_key)
    if heard is None:
        raise refused("request to turn signing off")
    print("signing off: the vehicle sends unsigned frames again")
    return EXIT_OK


def check_setup(args):
    args.key = key_from(args.passphrase, args.key_file, "signing setup")
    if args.key is None:
        raise usage("signing setup PASSPHRASE or --key-file FILE")
    if not any(args.key):
        raise usage("signing setup: an all-zero key turns signing off: use signing clear")
    args.current_key = key_from(args.current, args.current_key_file, "--current")


def check_clear(args):
    args.current_key = key_from(args.current, args.current_key_file, "--current")


def add_current(p):
    p.add_argument("--current", metavar="PASSPHRASE", help="the passphrase of the key the vehicle has now")
    p.add_argument("--current-key-file", metavar="FILE", help="the key the vehicle has now, from a file")


def register(sub):
    actions = group(sub, "signing", help="give the vehicle a MAVLink 2 signing key, or clear it")
    p = actions.add_parser("setup", help="SETUP_SIGNING with SHA-256(PASSPHRASE) (as MAVProxy) or a key file")
    p.add_argument("passphrase", nargs="?", metavar="PASSPHRASE")
    p.add_argument("--key-file", metavar="FILE", help="32 bytes, 64 hex digits, or a passphrase line")
    add_current(p)
    p.set_defaults(run=run_setup, check=check_setup)
    p = actions.add_parser("clear", help="turn signing off (SETUP_SIGNING with an all-zero key)")
    add_current(p)
    p.set_defaults(run=run_clear, check=check_clear)


if __name__ == "__main__":
    from mavctl import cli as mavctl_cli
    sys.exit(mavctl_cli.main(["signing"] + sys.argv[1:]))
