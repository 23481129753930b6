"""MAV_CMD names to ids, for registering a command handler by name (commands.handle).

The names live in the dialects' *_meta modules, which are large: each is imported only
for the look-up and dropped again, the seed's set first (it is the smaller), then
today's. Loaded on first use: a small board registers by id and never loads this.
Reference: docs/services/commands.md (Handlers).
"""
import gc
import sys


def command_id(name):
    """MAV_CMD id for a name such as 'NAV_TAKEOFF' or 'MAV_CMD_NAV_TAKEOFF'; ValueError
    for a name neither set has."""
    if not name.startswith("MAV_CMD_"):
        name = "MAV_CMD_" + name
    cid = None
    for meta in ("seed2012_meta", "common_meta"):
        module = "mavstack.dialects." + meta
        loaded = module in sys.modules
        try:
            cid = getattr(__import__(module, None, None, (name,)), name, None)
        except ImportError:  # not on this board
            continue
        finally:
            if not loaded and module in sys.modules:
                del sys.modules[module]
                package = sys.modules.get("mavstack.dialects")
                if package is not None and hasattr(package, meta):
                    delattr(package, meta)
                gc.collect()
        if cid is not None:
            return cid
    raise ValueError("unknown command " + name)
