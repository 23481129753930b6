"""mavctl: drive a MAVLink vehicle from the PC over UDP or a serial cable: parameters and
parameter files, missions and QGroundControl plans, commands, live telemetry, flashing.
One subcommand per run:

    mavctl params list                        # auto-connect: the one USB serial device,
    mavctl --connect udpout:127.0.0.1:14550 params list   # or a vehicle heard on UDP 14550
    mavctl --connect serial:/dev/ttyUSB0:57600 mission upload route.plan
    mavctl watch

`make setup` installs the command into .venv/bin (pyproject.toml: mavctl = mavctl_cli:entry);
`python host_tools/mavctl.py ...` runs the same thing from a checkout.

Layout (host_tools/):
    mavctl_cli.py       the command line, the plug-in list and convention (read it to add
                        a subcommand), the run that turns failures into one line + status
    mavctl_link.py      --connect specs, auto-connect, the first HEARTBEAT, open errors
    mavctl_vehicle.py   the Vehicle: commands, parameter and mission protocols, enum names
    mavctl_errors.py    Failure and the exit statuses
    mavctl_params.py    params: get, set, list; .params/.parm files (param_files.py)
    mavctl_mission.py   mission: .plan (plan_files.py) and QGC WPL (mission_files.py)
    mavctl_commands.py  command, arm, mode, reboot, stream, ports
    mavctl_progress.py  progress bars on a terminal
    mavctl_flash.py     `mavctl flash`, delegated to flash.py
    (the live view, plots, sim and signing are plug-ins of their own: mavctl_cli.PLUGINS)

Exit status: 0 done, 1 the vehicle refused (NACK) or did not answer, 2 usage error or
malformed file (nothing sent), 3 no port or port busy, 4 permission denied, 5 no
heartbeat, 6 not MicroPython, 7 .mpy version mismatch (mavctl_errors).
"""
import sys

from mavctl_cli import main

if __name__ == "__main__":
    sys.exit(main())
