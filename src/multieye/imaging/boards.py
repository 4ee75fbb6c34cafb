"""Several boards looked for in each image (rig.yaml's ``targets:``, docs/rig-yaml.md,
section 3.1): one image may show two boards, and gives one view per board.

:class:`Boards` is what a detection job carries instead of one
:class:`~multieye.imaging.targets.Target`: the boards a camera may see, by name.  Each board is
detected in the same decoded image (:func:`multieye.imaging.batch.process_array`), and the
board's own identity keeps it apart from the others: its marker ids (ChArUco, ArUco grid,
AprilGrid: markers of other ids are ignored by its detector) or, for a board without ids,
that it is the only such board the camera sees (rig.yaml refuses anything else,
:mod:`multieye.io.rig_targets`).  :func:`combined` joins the per-board results of one image.

Synopsis
--------
>>> from multieye.imaging.boards import Boards
>>> from multieye.imaging.targets import target_from_spec
>>> spec = {"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.16, "marker_size": 0.12,
...         "dictionary": "DICT_4X4_100"}
>>> boards = Boards((("north", target_from_spec(spec)),
...                  ("west", target_from_spec({**spec, "first_id": 20}))))
>>> boards.names, boards.kind
(('north', 'west'), 'charuco')
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from multieye.core.errors import InputError
from multieye.imaging.targets import Target

__all__ = ["Boards", "combined_reason"]


@dataclass(frozen=True)
class Boards:
    """The boards one camera looks for in each of its images.

    Attributes
    ----------
    boards : tuple of (str, Target)
        Name and board, in rig.yaml's order; at least one, names unique.
    """

    boards: tuple[tuple[str, Target], ...]

    def __post_init__(self):
        names = [n for n, _ in self.boards]
        if not names or len(set(names)) != len(names):
            raise InputError(f"boards need distinct names, at least one; got {names}")
        for name, board in self.boards:
            if not isinstance(board, Target):
                raise InputError(f"board {name!r} is not a Target: {type(board).__name__}")

    @classmethod
    def of(cls, targets: Mapping[str, Target]) -> Boards:
        """The boards of a mapping name -> board."""
        return cls(tuple(targets.items()))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self.boards)

    @property
    def kind(self) -> str:
        """The boards' types, ``+``-joined (for progress bars and messages)."""
        return "+".join(dict.fromkeys(b.kind for _, b in self.boards))

    def describe(self) -> str:
        """``charuco 5x7 north, charuco 5x7 west`` for messages."""
        return ", ".join(f"{b.kind} {b.rows}x{b.cols} {n}" for n, b in self.boards)


def combined_reason(boards: Boards, reasons: Mapping[str, str]) -> str:
    """Why an image with none of ``boards`` usable is left out: the reason of every board,
    ``target not detected (...)`` when no board was found at all."""
    if all(r.startswith("target not detected") for r in reasons.values()):
        return f"target not detected ({boards.describe()})"
    found = {n: r for n, r in reasons.items() if not r.startswith("target not detected")}
    first = next(iter(found.values()))
    kind = first.split(":", 1)[0].split(" (", 1)[0]
    details = "; ".join(f"{n}: {r}" for n, r in found.items())
    return f"{kind}: no board usable ({details})"
