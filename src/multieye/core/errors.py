"""Exceptions raised by multieye.

Every error a user can cause (bad arrays, weak motion, malformed files) is a
subclass of :class:`CalibrationError`.  The command line turns these into one
line on stderr and exit status 2; anything else is a bug and keeps its
traceback.
"""

from __future__ import annotations

__all__ = [
    "CalibrationError",
    "InputError",
    "TooFewMeasurementsError",
    "DegenerateMotionError",
    "DisconnectedError",
    "DatasetError",
    "UnprojectableStartError",
]


class CalibrationError(Exception):
    """Base class of every error a user can act on."""


class InputError(CalibrationError, ValueError):
    """Arrays of the wrong shape, NaN/inf, non-rigid matrices, mismatched counts."""


class TooFewMeasurementsError(CalibrationError):
    """A camera (or an unknown) has fewer measurements than the solver needs."""


class DegenerateMotionError(CalibrationError):
    """The motion does not determine the unknowns (e.g. rotations about one axis)."""


class DisconnectedError(CalibrationError):
    """Unknowns of a general problem that the measurement graph does not connect."""

    def __init__(self, message: str, names: tuple[str, ...] = ()):
        super().__init__(message)
        self.names = tuple(names)


class UnprojectableStartError(InputError):
    """A refinement's start puts target points of some images behind their camera (or
    outside its lens model); ``items`` names them, e.g. ``(camera, image)`` index pairs."""

    def __init__(self, message: str, items: tuple = ()):
        super().__init__(message)
        self.items = tuple(items)


class DatasetError(CalibrationError):
    """A file on disk is missing, unreadable or malformed.

    Parameters
    ----------
    message : str
        What is wrong and what was expected.
    path : str or os.PathLike, optional
        The file concerned.
    line : int, optional
        1-based line number in that file.
    camera : str, optional
        The camera concerned.
    """

    def __init__(self, message: str, path=None, line: int | None = None,
                 camera: str | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.camera = camera
        self.reason = message
        where = ""
        if self.path is not None:
            where = self.path + (f":{line}" if line is not None else "") + ": "
        elif line is not None:
            where = f"line {line}: "
        cam = f"camera {camera}: " if camera is not None else ""
        # One line whatever a file put into the message (a key or a name with a line break).
        super().__init__(" ".join(f"{where}{cam}{message}".splitlines()))
