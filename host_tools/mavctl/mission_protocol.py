"""The mission protocol as mavctl speaks it: uploading, downloading and clearing a
vehicle's mission, geofence and rally points (MAV_MISSION_TYPE 0, 1, 2), setting the
current item, and asking for home."""

from mavctl.errors import Failure
from mavctl.mission_file import Item
from mavctl.names import enum_name, mavlink

MISSION_TYPES = {"mission": 0, "fence": 1, "rally": 2}


class MissionProtocol:
    """vehicle.Vehicle's mission methods (it brings recv, for_me, command, mav and the
    target ids)."""

    def mission_upload(self, items, mtype, timeout=1.5, tries=5, progress=None):
        """MISSION_COUNT, answer each MISSION_REQUEST(_INT), until the MISSION_ACK;
        progress(done, total), if given, is told as items go."""
        n = len(items)
        self.mav.mission_count_send(self.target_system, self.target_component, n, mtype)
        asked = 1
        sent = set()
        kinds = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")
        while True:
            msg = self.recv(kinds, timeout if not sent else 3 * timeout,
                            lambda m: m.mission_type == mtype and self.for_me(m))
            if msg is None:
                if sent or asked >= tries:
                    raise Failure("upload stalled after %d of %d items" % (len(sent), n))
                self.mav.mission_count_send(self.target_system, self.target_component, n, mtype)
                asked += 1
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type != mavlink.MAV_MISSION_ACCEPTED:
                    raise Failure("upload refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
                if len(sent) == n:
                    return
                continue  # an ACCEPTED left over from an earlier transfer
            if msg.seq >= n:
                continue
            item = items[msg.seq]
            if msg.get_type() == "MISSION_REQUEST_INT":
                self.mav.send(item.to_int(self.mav, self.target_system, self.target_component, mtype))
            else:
                self.mav.send(item.to_float(self.mav, self.target_system, self.target_component, mtype))
            sent.add(msg.seq)
            if progress is not None:
                progress(len(sent), n)

    def mission_download(self, mtype, timeout=1.5, tries=5, progress=None):
        """MISSION_REQUEST_LIST -> COUNT, MISSION_REQUEST_INT each item, MISSION_ACK."""
        mine = (lambda m: m.mission_type == mtype and self.for_me(m))
        count = None
        for _ in range(tries):
            self.mav.mission_request_list_send(self.target_system, self.target_component, mtype)
            msg = self.recv(("MISSION_COUNT", "MISSION_ACK"), timeout, mine)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                raise Failure("download refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
            count = msg.count
            break
        if count is None:
            raise Failure("no answer to MISSION_REQUEST_LIST")
        items = []
        kinds = ("MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK")
        for seq in range(count):
            for _ in range(tries):
                self.mav.mission_request_int_send(self.target_system, self.target_component, seq, mtype)
                msg = self.recv(kinds, timeout,
                                lambda m: mine(m) and (m.get_type() == "MISSION_ACK" or m.seq == seq))
                if msg is None:
                    continue
                if msg.get_type() == "MISSION_ACK":
                    raise Failure("download refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
                items.append(Item.from_message(msg))
                if progress is not None:
                    progress(len(items), count)
                break
            else:
                raise Failure("no answer for item %d of %d" % (seq, count))
        self.mav.mission_ack_send(self.target_system, self.target_component,
                                  mavlink.MAV_MISSION_ACCEPTED, mtype)
        return items

    def home_position(self, timeout=1.5):
        """(lat, lon, alt) of the vehicle's HOME_POSITION, None if it does not say."""
        self.mav.command_long_send(self.target_system, self.target_component,
                                   mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                   mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
        msg = self.recv(("HOME_POSITION",), timeout)
        if msg is None:
            return None
        return msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1e3

    def mission_clear(self, mtype, tries=3, timeout=1.5):
        for _ in range(tries):
            self.mav.mission_clear_all_send(self.target_system, self.target_component, mtype)
            ack = self.recv(("MISSION_ACK",), timeout, lambda m: m.mission_type == mtype and self.for_me(m))
            if ack is None:
                continue
            if ack.type != mavlink.MAV_MISSION_ACCEPTED:
                raise Failure("clear refused: %s" % enum_name("MAV_MISSION_RESULT", ack.type))
            return
        raise Failure("no answer to MISSION_CLEAR_ALL")

    def mission_set_current(self, seq, tries=3, timeout=1.5):
        """MAV_CMD_DO_SET_MISSION_CURRENT; MISSION_SET_CURRENT where the command is unknown."""
        try:
            ack = self.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, [seq])
        except Failure:
            ack = None
        if ack is not None and ack.result != mavlink.MAV_RESULT_UNSUPPORTED:
            if ack.result != mavlink.MAV_RESULT_ACCEPTED:
                raise Failure("refused: %s" % enum_name("MAV_RESULT", ack.result))
            return
        for _ in range(tries):
            self.mav.mission_set_current_send(self.target_system, self.target_component, seq)
            msg = self.recv(("MISSION_CURRENT", "MISSION_ACK"), timeout,
                            lambda m: m.get_type() == "MISSION_ACK" and self.for_me(m) or
                            m.get_type() == "MISSION_CURRENT" and m.seq == seq)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type == mavlink.MAV_MISSION_ACCEPTED:
                    continue
                raise Failure("refused: %s" % enum_name("MAV_MISSION_RESULT", msg.type))
            return
        raise Failure("the vehicle did not change its current item to %d" % seq)
