"""The boards each camera of a rig looks for (rig.yaml's ``target:`` or ``targets:``,
docs/rig-yaml.md, section 3.1), and the detection results of several boards turned into one
result per (image, board) for :mod:`multieye.pipeline.camera_data`.

A camera that may see one board detects it as before (a
:class:`~multieye.imaging.targets.Target`); a camera that may see several detects them all
in each image (:class:`~multieye.imaging.boards.Boards`), and an image showing two boards
gives two views, one per board, at the same instant (:attr:`Observation.target
<multieye.pipeline.camera_data.Observation.target>`).
"""

from __future__ import annotations

from collections.abc import Mapping

from multieye.core.errors import DatasetError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.batch import ImageResult
from multieye.imaging.boards import Boards
from multieye.imaging.target_hints import counting_rule
from multieye.imaging.targets import Target, target_from_spec
from multieye.io import RejectedItem, Rig

__all__ = ["camera_boards", "intrinsics_boards", "per_board", "no_usable_image", "rejection_kind",
           "resized_hint"]


def camera_boards(rig: Rig, camera: str, built: Mapping[str, Target] | None = None
                  ) -> tuple[Target | Boards, tuple[str, ...]]:
    """What camera ``camera`` looks for in its images, and the names of those boards: its one
    board (a Target), or every board it may see (Boards, those whose ``cameras`` name it or
    that name none). ``built``: the rig's targets already built by name
    (:attr:`multieye.pipeline.rig_model.RigModel.targets`), used instead of building them again.

    Raises
    ------
    DatasetError
        No board of rig.yaml is for this camera (every one names other ``cameras``).
    """
    specs = {n: s for n, s in rig.targets.items() if s.sees(camera)}
    if not specs:
        raise DatasetError("no target of rig.yaml is seen by this camera (each names other "
                           "'cameras'); add it to the 'cameras' of the board it sees",
                           path=rig.path, camera=camera)
    built = built or {}
    made = {n: built[n] if n in built else target_from_spec(s, path=rig.path)
            for n, s in specs.items()}
    if len(made) == 1:
        return next(iter(made.values())), tuple(made)
    return Boards.of(made), tuple(made)


def intrinsics_boards(rig: Rig, camera: str, model) -> tuple[Target | Boards, tuple[str, ...]]:
    """What camera ``camera`` looks for in its ``intrinsics_images``: its own
    ``intrinsics_target`` (named ``"target"``), else the boards it looks for in its
    recording (:func:`camera_boards`), one view per (image, board) after :func:`per_board`.
    ``model``: the rig's targets built once (:class:`multieye.pipeline.rig_model.RigModel`).
    """
    own = model.intrinsics_targets.get(camera)
    if own is not None:
        return own, ("target",)
    return camera_boards(rig, camera, model.targets)


def per_board(stamped: list, results: list[ImageResult], looked_for: tuple[str, ...]
              ) -> tuple[list, list[ImageResult], list[str | None]]:
    """One entry per (image, board) from one result per image.

    Parameters
    ----------
    stamped : list of (float, str)
        Per image its stamp and label.
    results : list of ImageResult
        Per image its result; with several boards (``parts``), one per board inside.
    looked_for : tuple of str
        The names of the boards looked for (:func:`camera_boards`).

    Returns
    -------
    stamped, results, boards : lists of equal length
        An image with a usable board gives an entry per board that was found (usable, or
        found and then refused: PnP failed, bad fit); an image with none keeps its own
        result and board None.  A single board keeps the lists as they are, board its name.
    """
    if len(looked_for) == 1 and not any(r.parts for r in results):
        return list(stamped), list(results), [looked_for[0]] * len(results)
    out_stamped, out_results, boards = [], [], []
    for st, r in zip(stamped, results):
        found = [(n, p) for n, p in r.parts if p.detection is not None]
        if not r.ok or not found:
            out_stamped.append(st)
            out_results.append(r)
            boards.append(None)
            continue
        for n, p in found:
            out_stamped.append(st)
            out_results.append(p)
            boards.append(n)
    return out_stamped, out_results, boards


def rejection_kind(reason: str) -> str:
    """The kind of an image's rejection: the reason up to its details (``unreadable file``,
    ``wrong resolution``, ``target not detected``, ``PnP failed``, ``bad fit``)."""
    return reason.split(":", 1)[0].split(" (", 1)[0]


def _describe(rig: Rig) -> str:
    if not rig.targets:
        return "target"
    return ", ".join(f"{t.type} {t.rows}x{t.cols}" + (f" {n}" if len(rig.targets) > 1 else "")
                     for n, t in rig.targets.items())


def resized_hint(intrinsics: Intrinsics | None, results) -> str:
    """What a given lens without an image size says when its principal point is the centre
    of images about ``k`` times the size of these (both axes alike, ``k`` at least 1.3 or at
    most 0.77): intrinsics calibrated on images of another size (resized, binned, a camera
    mode), which makes every view a bad fit; ``""`` otherwise.  ``results`` are the camera's
    detection results (:class:`~multieye.imaging.batch.ImageResult`; their image sizes)."""
    size = next((r.image_size for r in results if getattr(r, "image_size", None)), None)
    if intrinsics is None or intrinsics.width is not None or size is None:
        return ""
    (w, h), (cx, cy) = size, intrinsics.K[:2, 2]
    kx, ky = cx / max((w - 1) / 2, 1.0), cy / max((h - 1) / 2, 1.0)
    if not (kx > 0 and ky > 0 and abs(kx / ky - 1) < 0.1 and not 0.77 < kx < 1.3):
        return ""
    return (f"; the intrinsics file states no image size and its principal point ({cx:.1f}, "
            f"{cy:.1f}) is the centre of images {(kx + ky) / 2:.2g} times the size of these "
            f"{w} x {h} ones: were the images resized after the intrinsics were calibrated? "
            "Use intrinsics for this image size and state image_width and image_height in the "
            "file")


def no_usable_image(rig: Rig, rejected: list[RejectedItem], n: int, hint: str = "") -> str:
    """Why a camera has no usable image, by kind, naming the first image of each kind; then
    ``hint`` (:func:`resized_hint`)."""
    kinds: dict[str, list[RejectedItem]] = {}
    for r in rejected:
        kinds.setdefault(rejection_kind(r.reason), []).append(r)
    if set(kinds) == {"target not detected"}:
        rule = "; ".join(dict.fromkeys(counting_rule(t.type) for t in rig.targets.values()))
        what, was = ("target", "was") if len(rig.targets) <= 1 else ("targets", "were")
        return (f"the {what} ({_describe(rig)}) {was} not detected in any of the {n} "
                f"images; check the target section of rig.yaml ({rule}) and the images; "
                "'multieye check' searches them for what they hold")
    parts = [f"{len(items)} {kind} (first {items[0].item}: {items[0].reason})"
             for kind, items in kinds.items()]
    return f"none of the {n} images is usable: " + "; ".join(parts) + hint

