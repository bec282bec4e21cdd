"""The pseudo-terminal loop the Python test devices share (faulty_gx1.py, faulty_mip.py).

A device object has `inbuf` (bytes from the host), `out` (bytes to send), `hold_until` (a
monotonic time before which nothing is sent or handled: a busy or stalled device),
`handle_input()` (handles what `inbuf` holds), `stream()` (queues the data due) and `report()`
(a JSON-able dict written to --report on SIGTERM).
"""

import json
import os
import select
import signal
import time
import tty


def serve(dev, link: str, report: str, poll_s: float = 0.002):
    """Opens a pty, points `link` at it and runs `dev` until SIGTERM."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    if os.path.lexists(link):
        os.unlink(link)
    os.symlink(os.ttyname(slave), link)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    try:
        while not stop:
            r, _, _ = select.select([master], [], [], poll_s)
            if r:
                try:
                    dev.inbuf += os.read(master, 4096)
                except (BlockingIOError, OSError):
                    pass
            if time.monotonic() >= dev.hold_until:
                dev.handle_input()
            # The device keeps sampling while the link is stalled; its data queues up.
            dev.stream()
            if dev.out and time.monotonic() >= dev.hold_until:
                try:
                    n = os.write(master, dev.out)
                    del dev.out[:n]
                except (BlockingIOError, OSError):
                    pass
    finally:
        with open(report, "w") as f:
            json.dump(dev.report(), f)
        os.unlink(link)
