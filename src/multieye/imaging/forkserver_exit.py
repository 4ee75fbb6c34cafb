"""The detection's fork server ends without the interpreter's teardown (issue 21).

The fork server imports numpy, OpenCV and the detection once (:data:`multieye.imaging.
workers.FORKSERVER_PRELOAD`, this module last).  When the main process ends,
:func:`multieye.imaging.workers.stop_helpers` closes the server's pipe and waits for it to
end, so that nothing is left behind, and the server then freed every module one by one: 40-90
ms of the command's end, for nothing.  Imported by the fork server, this module ends it at
its first exit function instead, once its streams are flushed (its listener and its
connections are closed by then).  Imported by any other process, it does nothing.
"""

from __future__ import annotations

import atexit
import os
import sys

from multieye.imaging.forkserver_later import in_fork_server

__all__ = ["ENDS_AT_ONCE"]


def _end_now() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):   # none, or closed
            pass
    os._exit(0)


#: Whether this process is a fork server that ends at its first exit function.
ENDS_AT_ONCE = in_fork_server()

if ENDS_AT_ONCE:
    atexit.register(_end_now)
