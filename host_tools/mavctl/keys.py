"""MAVLink 2 signing keys as mavctl reads them: from a passphrase (SHA-256 of it, as
MAVProxy derives it) or a key file (32 raw bytes, 64 hex digits, or else a passphrase
on its first line). Used by the link's --key options and `mavctl signing`."""
import hashlib

from mavctl.errors import usage


def passphrase_key(passphrase):
    """MAVProxy's key for a passphrase: SHA-256 of its bytes."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def read_key_file(path):
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise usage("%s: %s" % (path, e.strerror))
    if len(data) == 32:
        return data
    text = data.decode("utf-8", "replace").strip()
    if len(text) == 64:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    passphrase = text.splitlines()[0].strip() if text else ""
    if not passphrase:
        raise usage("%s: empty: a key file holds 32 bytes, 64 hex digits or a passphrase" % path)
    return passphrase_key(passphrase)


def key_from(passphrase, key_file, what):
    """The key of a passphrase or a key file (not both; `what` names the option in
    messages), None with neither."""
    if passphrase is not None and key_file is not None:
        raise usage("%s: a passphrase or a key file, not both" % what)
    if key_file is not None:
        return read_key_file(key_file)
    if passphrase is not None:
        if not passphrase:
            raise usage("%s: an empty passphrase" % what)
        return passphrase_key(passphrase)
    return None
