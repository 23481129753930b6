"""Names of MAVLink messages and enum values for mavctl, both ways (pymavlink's common
dialect, MAVLink 2), and the dialect module itself (`mavlink`) for its constants."""
import os

os.environ["MAVLINK20"] = "1"  # before pymavlink loads its dialect

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

from mavctl.errors import usage  # noqa: E402


def enum_name(enum, value):
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else "%s(%d)" % (enum, value)


def enum_value(enum, text):
    """An enum value from a number or a name, with or without the enum's prefix."""
    try:
        return int(text, 0)
    except ValueError:
        pass
    name = text.upper()
    for value, entry in mavlink.enums.get(enum, {}).items():
        if entry.name == name or entry.name == enum + "_" + name:
            return value
    raise usage("unknown %s: %s" % (enum, text))


def message_id(text):
    try:
        msgid = int(text, 0)
    except ValueError:
        msgid = getattr(mavlink, "MAVLINK_MSG_ID_" + text.upper(), None)
    if msgid is None or msgid not in mavlink.mavlink_map:
        raise usage("unknown message: %s" % text)
    return msgid


def message_name(msgid):
    cls = mavlink.mavlink_map.get(msgid)
    return cls.msgname if cls is not None else str(msgid)
