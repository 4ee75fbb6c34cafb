"""Whether worker processes may be started: they import the main script again.

Worker processes started by ``spawn`` or ``forkserver`` import the main script again (as
``__mp_main__``); when a script calls multieye at its top level, outside
``if __name__ == "__main__":``, every worker would run it again.  :func:`main_reimport_problem`
recognises that case (from the script's source and the running frame), and
:func:`threads_instead` says, with a warning, that work must run in threads of this process
instead.  Moved out of :mod:`multieye.imaging.batch`, which re-exports them.
"""

from __future__ import annotations

import ast
import os
import sys
import threading
import warnings
from functools import lru_cache

__all__ = ["main_reimport_problem", "threads_instead"]


def _is_main_guard(test: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either side), alone or as a term of an ``and``."""
    if isinstance(test, ast.BoolOp) and isinstance(test.op, ast.And):
        return any(_is_main_guard(v) for v in test.values)
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    return (any(isinstance(x, ast.Name) and x.id == "__name__" for x in sides)
            and any(isinstance(x, ast.Constant) and x.value == "__main__" for x in sides))


@lru_cache(maxsize=8)
def _guarded_lines(path: str, mtime_ns: int) -> tuple[tuple[int, int], ...] | None:
    """Line ranges of the bodies of the ``if __name__ == "__main__":`` blocks of a script;
    None when its source cannot be read or parsed."""
    try:
        with open(path, "rb") as f:
            tree = ast.parse(f.read(), filename=path)
    except (OSError, SyntaxError, ValueError):
        return None
    return tuple((node.body[0].lineno, node.body[-1].end_lineno) for node in ast.walk(tree)
                 if isinstance(node, ast.If) and _is_main_guard(node.test))


def _main_module_frame(main):
    """The frame running the main script's top level: in this thread, else the main thread."""
    candidates = [sys._getframe()]
    main_thread = sys._current_frames().get(threading.main_thread().ident)
    if main_thread is not None:
        candidates.append(main_thread)
    for frame in candidates:
        while frame is not None:
            if frame.f_globals is main.__dict__ and frame.f_code.co_name == "<module>":
                return frame
            frame = frame.f_back
    return None


def main_reimport_problem() -> str | None:
    """Why worker processes cannot be started safely now, or None when they can.

    Workers started by ``spawn`` or ``forkserver`` import the main script again (as
    ``__mp_main__``), so that what it defines can be unpickled.  That is harmless when the
    script's top level only defines things and calls multieye under
    ``if __name__ == "__main__":``; when the call runs at the top level itself, every worker
    would run it again (and multiprocessing stops it with an error).  There is no main
    script to import in an interactive session, a notebook or ``python -c``.

    Returns
    -------
    str or None
        What is wrong, for a message: the call at the script's top level, outside
        ``if __name__ == "__main__":``, or a script whose source cannot be read to tell.
    """
    main = sys.modules.get("__main__")
    if main is None:
        return None
    path = getattr(main, "__file__", None)
    spec = getattr(main, "__spec__", None)
    if path is None or (spec is None and os.path.splitext(os.path.basename(path))[0] == "ipython"):
        return None       # multiprocessing imports nothing as the main module then
    frame = _main_module_frame(main)
    if frame is None:
        return (f"the main script {path} is not running this call from its top level, so "
                "whether importing it again would run it cannot be told")
    try:
        guarded = _guarded_lines(os.path.abspath(path), os.stat(path).st_mtime_ns)
    except OSError:
        guarded = None
    if guarded is None:
        return f"the main script {path} cannot be read to tell whether it is safe to import"
    line = frame.f_lineno
    if any(lo <= line <= hi for lo, hi in guarded):
        return None
    return (f"{path} calls multieye at its top level (line {line}), outside "
            "`if __name__ == \"__main__\":`, and worker processes would run it again")


def threads_instead(n_workers: int) -> bool:
    """True, with a warning saying why, when worker processes must not be started."""
    if n_workers <= 1:
        return False
    problem = main_reimport_problem()
    if problem is None:
        return False
    # point the warning at the script's line that called multieye
    main = sys.modules["__main__"]
    frame, level = sys._getframe(), 1
    while frame is not None and not (frame.f_globals is main.__dict__
                                     and frame.f_code.co_name == "<module>"):
        frame, level = frame.f_back, level + 1
    warnings.warn(f"multieye: detecting in {n_workers} threads of this process instead of "
                  f"worker processes: {problem}. Put the call under "
                  "`if __name__ == \"__main__\":` to detect in worker processes.",
                  RuntimeWarning, stacklevel=level if frame is not None else 2)
    return True
