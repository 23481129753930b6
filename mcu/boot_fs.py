"""Frozen as _boot.py into the emulated board's firmware with a filesystem (mcu/firmware.py
build_with_filesystem): run at every reset, it mounts littlefs over a RAM region outside
the GC heap at /flash and makes that the current directory, as a board mounts its flash.
The region keeps its contents across soft resets (not power-off): a blank one, as at
power-on, is formatted. firmware.py fills REGION in from the profile's FS_REGION.
"""
REGION = (0, 0)  # (start, size): boards/<board>.py FS_REGION


def _mount(start, size, block=512):
    # Everything stays local: this runs in __main__, whose globals the REPL shares.
    import os
    import uctypes
    import vfs

    class RamBlockDevice:
        """littlefs' block device over the region (the extended interface: offsets, erase)."""

        def __init__(self):
            self.mem = memoryview(uctypes.bytearray_at(start, size))

        def readblocks(self, n, buf, off=0):
            a = n * block + off
            buf[:] = self.mem[a:a + len(buf)]

        def writeblocks(self, n, buf, off=0):
            a = n * block + off
            self.mem[a:a + len(buf)] = buf

        def ioctl(self, op, arg):
            if op == 4:  # block count
                return size // block
            if op == 5:  # block size
                return block
            return 0  # init, deinit, sync, erase: nothing to do in RAM

    dev = RamBlockDevice()
    try:
        fs = vfs.VfsLfs2(dev, mtime=False)
    except OSError:  # no filesystem there yet
        vfs.VfsLfs2.mkfs(dev)
        fs = vfs.VfsLfs2(dev, mtime=False)
    vfs.mount(fs, "/flash")
    os.chdir("/flash")


_mount(*REGION)
del _mount
