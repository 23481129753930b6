"""Progress bars for transfers that take more than a moment (parameter download, mission
transfer, flashing): tqdm on stderr when it is a terminal, nothing in a pipe or a log.

    with progress("parameters") as bar:     # total unknown until the first answer
        bar(done, total)                     # call as often as you like
"""
import contextlib
import sys


@contextlib.contextmanager
def progress(what, total=None, stream=None, delay=0.5):
    """A callable bar(done, total=None) that draws a bar on a terminal; a no-op elsewhere.
    The bar appears only after `delay` seconds, so quick transfers stay quiet."""
    stream = stream if stream is not None else sys.stderr
    if not getattr(stream, "isatty", lambda: False)():
        yield lambda done, total=None: None
        return
    from tqdm import tqdm
    bar = tqdm(total=total, desc=what, unit="", file=stream, delay=delay, leave=False,
               dynamic_ncols=True)

    def update(done, total=None):
        if total is not None and total != bar.total:
            bar.total = total
            bar.refresh()
        if done != bar.n:
            bar.update(done - bar.n)

    try:
        yield update
    finally:
        bar.close()
