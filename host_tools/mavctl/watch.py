"""`mavctl watch`: the vehicle at a glance, refreshed in place on a terminal: mode and
armed state, position and altitude, battery, GPS, link quality (the radio's RADIO_STATUS
and the drop rate measured from sequence numbers), the last STATUSTEXTs and the message
rate table. In a pipe, or with message names given, it prints messages one a line
(`--view` prints the view once a second instead); `--tlog FILE` records the session as a
telemetry log (tlog.py)."""
import math
import shutil
import sys
import time

from mavctl.errors import EXIT_OK
from mavctl.tlog import TlogWriter
from mavctl.names import enum_name, message_id, message_name

from pymavlink import mavutil

REFRESH_S = 0.5        # how often the terminal view is redrawn
LINE_VIEW_S = 1.0      # how often --view prints in a pipe
RATE_WINDOW_S = 5.0    # rates and drop rate are measured over this much recent time
STATUSTEXTS = 5        # how many of the vehicle's last messages the view shows
RADIO_STATUS = "RADIO_STATUS"
LINK_FLOW = "LINK_FLOW"  # the vehicle's NAMED_VALUE_INT: its link's budget in percent (radio flow control)
MAV_MODE_FLAG_SAFETY_ARMED = 128
GPS_FIX = {0: "no GPS", 1: "no fix", 2: "2D fix", 3: "3D fix", 4: "DGPS", 5: "RTK float",
           6: "RTK fixed", 7: "static", 8: "PPP"}


class Window:
    """Events counted per kind over the last RATE_WINDOW_S seconds (one bucket a second)."""

    def __init__(self):
        self.buckets = []  # [second, {kind: count}], oldest first

    def add(self, now, kind, n=1):
        second = int(now)
        if not self.buckets or self.buckets[-1][0] != second:
            self.buckets.append([second, {}])
        counts = self.buckets[-1][1]
        counts[kind] = counts.get(kind, 0) + n

    def totals(self, now):
        """{kind: count} over the window, and the window's length in seconds."""
        while self.buckets and self.buckets[0][0] <= now - RATE_WINDOW_S:
            self.buckets.pop(0)
        out = {}
        for _, counts in self.buckets:
            for kind, n in counts.items():
                out[kind] = out.get(kind, 0) + n
        span = now - self.buckets[0][0] if self.buckets else 0.0
        return out, max(1.0, min(RATE_WINDOW_S, span))


class LinkQuality:
    """Frames lost, from the gaps in each sender's sequence numbers (per system and
    component, as each counts on its own)."""

    def __init__(self):
        self.last_seq = {}
        self.received = 0
        self.lost = 0
        self.recent = Window()

    def frame(self, msg, now):
        key = (msg.get_srcSystem(), msg.get_srcComponent())
        seq = msg.get_seq()
        last = self.last_seq.get(key)
        self.last_seq[key] = seq
        self.received += 1
        self.recent.add(now, "rx")
        if last is not None:
            gap = (seq - last - 1) & 0xFF
            if gap < 128:  # a larger "gap" is a duplicate or a frame late, not a loss
                self.lost += gap
                self.recent.add(now, "lost", gap)

    def drop_text(self, now):
        counts, _ = self.recent.totals(now)
        rx, lost = counts.get("rx", 0), counts.get("lost", 0)
        total = self.received + self.lost
        recent = 100.0 * lost / (rx + lost) if rx + lost else 0.0
        overall = 100.0 * self.lost / total if total else 0.0
        return "drop %.1f%% now, %.1f%% overall (%d lost of %d)" % (recent, overall, self.lost, total)


class WatchState:
    """What the view shows, from the messages of one vehicle (and its radio)."""

    def __init__(self, target_system):
        self.target_system = target_system
        self.started = time.monotonic()
        self.latest = {}           # message type -> last message
        self.seen_at = {}          # message type -> when
        self.rates = Window()
        self.counts = {}
        self.link = LinkQuality()
        self.texts = []            # (when, severity, text), newest last
        self.flow = None           # (the vehicle's LINK_FLOW percent, when)

    def feed(self, msg, now):
        kind = msg.get_type()
        self.latest[kind] = msg
        self.seen_at[kind] = now
        self.counts[kind] = self.counts.get(kind, 0) + 1
        self.rates.add(now, kind)
        if kind != RADIO_STATUS:  # radios number their own frames
            self.link.frame(msg, now)
        if kind == "NAMED_VALUE_INT" and msg.name == LINK_FLOW:
            self.flow = (msg.value, now)
        if kind == "STATUSTEXT":
            self.texts.append((now, msg.severity, msg.text))
            del self.texts[:-STATUSTEXTS]

    # --- the view, as lines

    def lines(self, now, rows=None):
        out = ["mavctl watch: system %s, %s" % (self.target_system, age(now - self.started))]
        for section in (self.mode_line, self.position_line, self.battery_line, self.gps_line,
                        self.radio_line):
            out.append(section(now))
        out.append("link     " + self.link.drop_text(now))
        out.append("")
        out.append("messages (last %d):" % STATUSTEXTS)
        if not self.texts:
            out.append("  (none)")
        for when, severity, text in self.texts:
            name = enum_name("MAV_SEVERITY", severity).replace("MAV_SEVERITY_", "")
            out.append("  %6s ago  %-9s %s" % (age(now - when), name, text))
        out.append("")
        out.extend(self.rate_lines(now, None if rows is None else max(3, rows - len(out) - 1)))
        return out

    def _get(self, kind, now, stale=5.0):
        msg = self.latest.get(kind)
        if msg is None or now - self.seen_at[kind] > stale:
            return None
        return msg

    def mode_line(self, now):
        hb = self._get("HEARTBEAT", now)
        if hb is None:
            return "mode     (no HEARTBEAT for 5 s)"
        armed = "ARMED" if hb.base_mode & MAV_MODE_FLAG_SAFETY_ARMED else "disarmed"
        state = enum_name("MAV_STATE", hb.system_status).replace("MAV_STATE_", "")
        return "mode     %s  %s  (%s, %s)" % (mavutil.mode_string_v10(hb), armed, state,
                                             enum_name("MAV_TYPE", hb.type).replace("MAV_TYPE_", ""))

    def position_line(self, now):
        pos = self._get("GLOBAL_POSITION_INT", now)
        hud = self._get("VFR_HUD", now)
        if pos is None:
            return "position (no GLOBAL_POSITION_INT)"
        text = "position %.7f %.7f  alt %.1f m (%.1f m above home)" % (
            pos.lat / 1e7, pos.lon / 1e7, pos.alt / 1e3, pos.relative_alt / 1e3)
        if hud is not None:
            text += "  %.1f m/s  heading %d  climb %.1f m/s" % (hud.groundspeed, hud.heading, hud.climb)
        else:
            text += "  %.1f m/s" % (math.hypot(pos.vx, pos.vy) / 100.0)
        home = self.latest.get("HOME_POSITION")
        if home is not None:
            text += "  %.0f m from home" % from_home(pos, home)
        return text

    def battery_line(self, now):
        bat = self._get("BATTERY_STATUS", now)
        sys_status = self._get("SYS_STATUS", now)
        if bat is not None:
            cells = [v for v in bat.voltages if v != 0xFFFF]
            volts = sum(cells) / 1000.0 if cells else float("nan")
            current = bat.current_battery / 100.0 if bat.current_battery >= 0 else float("nan")
            left = "%d%%" % bat.battery_remaining if bat.battery_remaining >= 0 else "?%"
            used = "  %d mAh used" % bat.current_consumed if bat.current_consumed >= 0 else ""
            return "battery  %.2f V  %.1f A  %s%s" % (volts, current, left, used)
        if sys_status is not None:
            left = "%d%%" % sys_status.battery_remaining if sys_status.battery_remaining >= 0 else "?%"
            return "battery  %.2f V  %.1f A  %s" % (sys_status.voltage_battery / 1000.0,
                                                    sys_status.current_battery / 100.0, left)
        return "battery  (no BATTERY_STATUS or SYS_STATUS)"

    def gps_line(self, now):
        gps = self._get("GPS_RAW_INT", now)
        if gps is None:
            return "gps      (no GPS_RAW_INT)"
        sats = "?" if gps.satellites_visible == 255 else str(gps.satellites_visible)
        hdop = "?" if gps.eph == 0xFFFF else "%.2f" % (gps.eph / 100.0)
        return "gps      %s  %s satellites  hdop %s" % (GPS_FIX.get(gps.fix_type, gps.fix_type), sats, hdop)

    def radio_line(self, now):
        r = self._get(RADIO_STATUS, now, stale=10.0)
        if r is None:
            text = "radio    (no RADIO_STATUS: not a radio link, or the radio does not send it)"
        else:
            text = ("radio    rssi %d/%d  noise %d/%d (local/remote)  txbuf %d%%  rx errors %d  fixed %d"
                    % (r.rssi, r.remrssi, r.noise, r.remnoise, r.txbuf, r.rxerrors, r.fixed))
        if self.flow is not None and now - self.flow[1] <= 10.0:
            # The vehicle's radio flow control: its link's budget, streams with it.
            text += "  vehicle sends at %d%% (flow control)" % self.flow[0]
        return text

    def rate_lines(self, now, room=None):
        counts, span = self.rates.totals(now)
        names = sorted(counts, key=lambda k: (-counts[k], k))
        out = ["%-28s %8s %8s" % ("MESSAGE", "COUNT", "HZ")]
        shown = names if room is None or len(names) <= room else names[:room - 1]
        for name in shown:
            out.append("%-28s %8d %8.1f" % (name, self.counts[name], counts[name] / span))
        if len(shown) < len(names):
            out.append("... %d more" % (len(names) - len(shown)))
        return out


def from_home(pos, home):
    """Metres over the ground from home (equirectangular: fine over a flight's distances)."""
    k = math.cos(math.radians(home.latitude / 1e7))
    north = (pos.lat - home.latitude) / 1e7 * 111319.49
    east = (pos.lon - home.longitude) / 1e7 * 111319.49 * k
    return math.hypot(north, east)


def age(seconds):
    seconds = max(0, int(seconds))
    if seconds < 60:
        return "%ds" % seconds
    return "%dm%02ds" % divmod(seconds, 60)


class Screen:
    """Draws the view in place on a terminal (ANSI: home, clear to end of line/screen)."""

    def __init__(self, out):
        self.out = out
        self.out.write("\x1b[?25l\x1b[H\x1b[2J")  # hide the cursor, clear once

    def draw(self, lines):
        size = shutil.get_terminal_size((100, 40))
        lines = [line[:size.columns - 1] for line in lines[:size.lines - 1]]
        self.out.write("\x1b[H" + "".join(line + "\x1b[K\n" for line in lines) + "\x1b[J")
        self.out.flush()

    def close(self):
        self.out.write("\x1b[?25h")
        self.out.flush()


def receive(v, wanted, timeout):
    """Next frame from the vehicle, or a RADIO_STATUS from whoever sends it (a radio has
    its own system id), or None after timeout."""
    v.heartbeat()
    msg = v.conn.recv_match(blocking=True, timeout=timeout)
    if msg is None:
        return None
    kind = msg.get_type()
    if kind == "BAD_DATA":
        return None
    if msg.get_srcSystem() != v.target_system and kind != RADIO_STATUS:
        return None
    if wanted is not None and kind not in wanted:
        return None
    return msg


def run_watch(v, args):
    v.echo_statustext = False
    tty = sys.stdout.isatty()
    view = args.view or (tty and not args.messages and not args.rates)
    log = args.tlog_writer
    if log is not None:
        log.attach(v.conn)
    state = WatchState(v.target_system)
    screen = Screen(sys.stdout) if view and tty else None
    start = time.monotonic()
    end = start + args.seconds if args.seconds else math.inf
    next_draw = start + (REFRESH_S if screen else LINE_VIEW_S)
    wanted = None if view else args.wanted
    try:
        while True:
            now = time.monotonic()
            if now >= end:
                break
            msg = receive(v, wanted, min(0.2, end - now, max(0.0, next_draw - now) + 0.01))
            now = time.monotonic()
            if msg is not None:
                state.feed(msg, now)
                if not view and not args.rates:
                    print(msg, flush=True)
            if view and now >= next_draw:
                next_draw = now + (REFRESH_S if screen else LINE_VIEW_S)
                show(state, screen, now)
    except KeyboardInterrupt:
        pass
    finally:
        if screen is not None:
            screen.close()
        if log is not None:
            log.close()
    now = time.monotonic()
    if view and screen is None:
        show(state, None, now)
    if args.rates:
        print("%-28s %8s %8s" % ("MESSAGE", "COUNT", "HZ"))
        seconds = max(now - start, 1e-3)
        for name in sorted(state.counts):
            print("%-28s %8d %8.2f" % (name, state.counts[name], state.counts[name] / seconds))
    if log is not None:
        print("mavctl: %d frames logged to %s" % (log.frames, args.tlog), file=sys.stderr)
    sys.stdout.flush()
    return EXIT_OK


def show(state, screen, now):
    if screen is not None:
        screen.draw(state.lines(now, shutil.get_terminal_size((100, 40)).lines - 1))
    else:
        print("\n".join(state.lines(now)) + "\n", flush=True)


def check_watch(args):
    args.wanted = {message_name(message_id(m)) for m in args.messages} or None
    # Opened before connecting: a path that cannot be written is refused at once.
    args.tlog_writer = TlogWriter(args.tlog) if args.tlog else None


def register(sub):
    p = sub.add_parser("watch", help="the vehicle at a glance, live (messages one a line in a pipe)")
    p.add_argument("messages", nargs="*", metavar="MSG",
                   help="print only these messages, one a line (default on a terminal: the live view)")
    p.add_argument("--seconds", type=float, help="stop after this long (default: Ctrl-C)")
    p.add_argument("--rates", action="store_true", help="print a table of message rates at the end")
    p.add_argument("--view", action="store_true",
                   help="the live view even in a pipe (printed once a second)")
    p.add_argument("--tlog", metavar="FILE", help="record a telemetry log (.tlog) of the session")
    p.set_defaults(run=run_watch, check=check_watch)


if __name__ == "__main__":
    from mavctl import cli as mavctl_cli
    sys.exit(mavctl_cli.main(["watch"] + sys.argv[1:]))
