"""mavctl: drive a MAVLink vehicle from the PC over UDP or a serial cable: parameters and
their files, missions and QGroundControl plans, commands, live telemetry, plots, logs,
signing, the simulated vehicle on a pty, flashing. One subcommand per run, each from a
plug-in module (cli.PLUGINS). Reference: docs/mavctl.md.
"""
import os

HOST_TOOLS = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROOT = os.path.dirname(HOST_TOOLS)  # the checkout: boards/, firmware/, .venv/
