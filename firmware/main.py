"""The program a board runs: start its watchdog, build the endpoint its profile
describes, then poll forever, feeding the watchdog.

    micropython firmware/main.py --board unix --link udpout:127.0.0.1:14550 --storage DIR
Options: --board NAME, --link SPEC (repeatable: udpout:HOST:PORT, udpin:ADDR:PORT,
serial:DEVICE:BAUD), --storage DIR, --sysid N, --set NAME=VALUE (board option,
repeatable). On a board, with no arguments, the profile flashed as board.py is used.
Reference: docs/core.md; the board settings: docs/boards.md; the watchdog and safe
mode: docs/reliability.md.
"""
import gc
import sys

from mavstack.compat import ticks_ms, ticks_add, ticks_diff
from mavstack.endpoint import Endpoint, Reboot, Shutdown
from mavstack.faults import APP
from mavstack.services import compose
from mavstack.storage import Storage
from mavstack.transport import open_transport


def parse_args(argv):
    opts = {"board": None, "links": [], "storage": None, "sysid": None, "options": {}}
    i = 0
    while i < len(argv):
        arg = argv[i]
        val = argv[i + 1] if i + 1 < len(argv) else None
        if arg == "--board":
            opts["board"] = val
        elif arg == "--link":
            opts["links"].append(val)
        elif arg == "--storage":
            opts["storage"] = val
        elif arg == "--sysid":
            opts["sysid"] = int(val)
        elif arg == "--set":
            key, _, value = val.partition("=")
            opts["options"][key] = value
        else:
            raise SystemExit("unknown argument: %s (see firmware/main.py)" % arg)
        i += 2
    return opts


def load_board(name):
    if name is None:
        import board  # the profile flashed onto the device

        return board
    # Running from the repository: profiles live in ../boards.
    boards = (__file__ if "/" in __file__ else "./" + __file__).rsplit("/", 1)[0] + "/../boards"
    if boards not in sys.path:
        sys.path.append(boards)
    return __import__(name)


def watchdog(board, opts):
    """The board's watchdog started (WATCHDOG_MS, --set watchdog_ms=N; 0: none) -> an
    object with feed(), and stop() where it can be stopped; None when there is none."""
    ms = int(opts["options"].get("watchdog_ms", getattr(board, "WATCHDOG_MS", 2000)))
    return board.watchdog(ms) if ms and hasattr(board, "watchdog") else None


def build(board, opts, dog=None):
    """Endpoint, links, storage and services as the board profile composes them; with
    a watchdog (dog, fed meanwhile), the crash-loop guard first (mavstack/watchdog.py)."""
    # --set dialect=seed2012 runs the board with the seed's message set instead of its own.
    name = opts.get("options", {}).get("dialect") or board.DIALECT
    dialect = __import__("mavstack.dialects." + name, None, None, ("CRC_LEN",))
    sysid = opts.get("sysid") or getattr(board, "SYSID", 1)
    # "follow" (a peripheral): 0 until the autopilot's HEARTBEAT tells it (services/peripheral/)
    ep = Endpoint(dialect, 0 if sysid == "follow" else sysid, getattr(board, "COMPID", 1))
    ep.board = board
    ep.options = opts.get("options", {})
    offset = ep.setting("UPTIME_OFFSET_MS", 0)  # tests: start late, to see uptimes past 2^30
    if offset:
        from mavstack.uptime import Clock  # (only then: a board may do without the clock)

        ep.clock = Clock(ep.now, offset)
    if opts.get("storage") or not hasattr(board, "storage"):
        ep.storage = Storage(opts.get("storage") or board.STORAGE)
    else:
        ep.storage = board.storage()  # a board without a filesystem (storage_ram.py)
    guard = None
    if dog is not None:
        # A board its watchdog restarts counts its starts, and may start in safe mode.
        from mavstack.watchdog import Guard  # only then (RAM)

        guard = ep.add(Guard(board.SERVICES))
    # --link, repeated; or --set links=SPEC,SPEC; or the profile's transports().
    specs = opts.get("links") or [s for s in ep.options.get("links", "").split(",") if s]
    # --set udp_bytes_per_s=5760 makes UDP links pace themselves like a 57600 baud radio.
    udp_rate = ep.setting("UDP_BYTES_PER_S", 200000)
    if specs:
        for spec in specs:
            ep.add_link(open_transport(spec, udp_rate, ep.setting("UDP_RX_CHUNK", 0)))
    else:
        # --set baud=N: the board's own links budget as if at N baud (bench_mcu_load.py).
        baud = ep.setting("BAUD_BUDGET", 0)
        for transport in board.transports():
            if baud:
                transport.bytes_per_s = baud // 10
            ep.add_link(transport)
    _routing(ep)
    if dog is not None:
        dog.feed()
    # Each after the services it needs (in safe mode, those the guard leaves).
    why = None
    if ep.sysid == 0 and "peripheral" not in board.SERVICES:
        why = 'SYSID "follow" needs the peripheral service: add it to SERVICES'
    why = why or compose(ep, board.SERVICES if guard is None else guard.services)
    if why:  # the profile's SERVICES are wrong: say so in one line, and stop
        print("mavstack: board %s: %s" % (board.NAME, why))
        sys.exit(1)
    if dog is not None:
        dog.feed()
    # --set application=0: the stack alone (the unix simulator allocates, so a soak under
    # heap_lock runs without it). None in safe mode.
    app = None
    if hasattr(board, "application") and ep.setting("APPLICATION", True) and not (guard and guard.safe):
        app = board.application(ep)
    _check_ram(ep, board)
    return ep, app


def _routing(ep):
    """Routing between the links (mavstack/router.py): on by default with more than one
    link (ROUTING, --set routing=0/1); ROUTES entries, forgotten after ROUTE_TIMEOUT_MS of
    silence; PRIVATE_LINKS: link indexes ("1,2") nothing is forwarded to or from, as is a
    transport whose `private` is True. Reference: docs/routing.md."""
    if not ep.setting("ROUTING", len(ep.links) > 1):
        return
    from mavstack.router import Router  # only then (RAM)

    private = 0
    for i in str(ep.setting("PRIVATE_LINKS", "")).replace(",", " ").split():
        private |= 1 << int(i)
    for link in ep.links:
        if getattr(link.transport, "private", False):
            private |= 1 << link.index
    ep.add(Router(ep.setting("ROUTES", 16), ep.setting("ROUTE_TIMEOUT_MS", 10000), private))


def _check_ram(ep, board):
    """Say how much heap the built vehicle holds, and warn when it is over the board's budget."""
    if not hasattr(gc, "mem_alloc"):
        return  # CPython
    gc.collect()
    used = gc.mem_alloc()
    budget = getattr(board, "RAM_BUDGET", 0)
    print("mavstack: %s ready, %d KB of heap in use (budget %d KB)" % (board.NAME, used >> 10, budget >> 10))
    if budget and used > budget:
        ep.statustext(4, "RAM: %d KB in use, budget %d KB" % (used >> 10, budget >> 10))


def run(ep, app=None, dog=None):
    """Poll, then sleep until the next work is due or a byte arrives (sleeper.py)."""
    # Sleeping through status.idle lets it measure the loop's load for SYS_STATUS.
    from mavstack.sleeper import Sleeper  # (here: the vehicle is built, its garbage gone)

    status = ep.services.get("status")
    sleep = Sleeper(ep.links).sleep
    # HEAP_LOCK (--set heap_lock=1): the loop must not allocate, and a MemoryError
    # says where it did.
    lock = ep.setting("HEAP_LOCK", False) and hasattr(gc, "mem_alloc")
    # HEAP_REPORT_MS (--set heap_report_ms=N): print the heap in use and what mem_total()
    # moved by since the last report, every N ms (the soak test reads these lines).
    report_ms = ep.setting("HEAP_REPORT_MS", 0) if hasattr(gc, "mem_alloc") else 0
    if lock or report_ms:
        import micropython

        gc.collect()
    if report_ms:
        _REPORT[0] = micropython.mem_total()
        _REPORT[1] = ticks_ms()
    if lock:
        micropython.heap_lock()
    app_due = ticks_ms()
    try:
        while True:
            if dog is not None:
                dog.feed()
            now = ticks_ms()
            ep.poll(now)
            if app is not None:
                # Ticked as a service is: when due, or on a pass every service ran.
                if ep.all_due or ticks_diff(now, app_due) >= 0:
                    app_due = ticks_add(now, _app(ep, app, now))
                else:
                    ep.until(ticks_diff(app_due, now))
            if report_ms and ticks_diff(now, _REPORT[1]) >= report_ms:
                _REPORT[1] = now
                _heap_report(lock)
            if status is not None:
                status.idle(ep.wait_ms, sleep)
            else:
                sleep(ep.wait_ms)
    except MemoryError as e:
        if lock:
            micropython.heap_unlock()
            print("mavstack: MemoryError with the heap locked")
            sys.print_exception(e)
        raise
    finally:
        if lock:
            micropython.heap_unlock()


def _app(ep, app, now):
    """The application's tick -> ms to its next: its raising is a fault, not the end;
    what it returns (ms to its next work, None: the next pass) bounds the loop's sleep,
    as a service's does."""
    faults = ep.faults
    ms = faults.tick(app, now)
    if faults.error is not None:
        faults.count(APP, 0)
        ms = 1
    elif ms is None:
        ms = 1
    ep.until(ms)
    return ms


_REPORT = [0, 0]  # mem_total() after the last heap report, and when it was made


def _heap_report(lock):
    import micropython

    moved = micropython.mem_total() - _REPORT[0]
    used = gc.mem_alloc()
    if lock:
        micropython.heap_unlock()  # printing allocates: what it takes is not counted
    print("mavstack: heap", used, "moved", moved, "locked" if lock else "unlocked")
    if lock:
        micropython.heap_lock()
    _REPORT[0] = micropython.mem_total()


def main(argv):
    opts = parse_args(argv)
    board = load_board(opts["board"])
    dog = watchdog(board, opts)  # first: whatever follows may hang
    while _session(board, opts, dog):
        # A reboot in place: the old vehicle went with _session's frame (a small heap holds
        # one vehicle, not two; the collector scans the live frames, where a stale slot
        # would have kept it). The watchdog runs on.
        gc.collect()


def _session(board, opts, dog):
    """Build and run one vehicle -> True to start another in its place."""
    ep, app = build(board, opts, dog)
    try:
        run(ep, app, dog)
    except Reboot:
        # A board resets in board.reset() (or its watchdog's reset()); the unix vehicle
        # (and a board with neither) restarts in place.
        stop(ep)
        ep.close()
        if hasattr(board, "reset"):
            board.reset()
        if hasattr(dog, "reset"):
            # A watchdog that can reset the board (the emulated M3's) does, as a real
            # board's reset() does: in a small heap the next vehicle may not find room
            # among the pieces this one left (out of safe mode, or with an application).
            dog.reset()
        return True
    except (KeyboardInterrupt, Shutdown):
        pass
    stop(ep)
    ep.close()
    if dog is not None and hasattr(dog, "stop"):  # back to the REPL, or out
        dog.stop()
    elif dog is not None:
        print("mavstack: the watchdog runs on (machine.WDT cannot be stopped)")
    return False


def stop(ep):
    """Before a reboot or shutdown: services that keep something across it store it now
    (signing: its timestamp, so that frames from before cannot be replayed after; the
    crash-loop guard: that this start ended cleanly)."""
    for svc in ep.services.values():
        if hasattr(svc, "stop"):
            svc.stop()


if __name__ == "__main__":
    main(sys.argv[1:])
