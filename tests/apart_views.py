"""A rig of two overlapping cameras whose views of the board never share an instant: each sees
it in one half of the recording only (the other half's images grey), so the views link no
camera to the other (tests of `check` and of the overlap solve)."""

from __future__ import annotations

from pathlib import Path


def render_apart(ds: Path) -> Path:
    """Two cameras 10 degrees apart, 8 instants, 320 x 240, a 4 x 5 chessboard of 80 mm: cam0
    sees the board at the first four instants, cam1 at the last four; returns ``ds``."""
    import cv2
    import numpy as np

    from multieye.sim.overlap import OverlapSpec, render_overlap_dataset

    render_overlap_dataset(ds, OverlapSpec(n_cameras=2, angle_deg=10, n_instants=8,
                                           width=320, height=240, fisheye=(),
                                           target={"type": "chessboard", "rows": 4, "cols": 5,
                                                   "spacing": 0.08}))
    grey = np.full((240, 320), 128, np.uint8)
    for j, half in ((0, slice(4, 8)), (1, slice(0, 4))):
        for p in sorted((ds / f"cam{j}").iterdir())[half]:
            cv2.imwrite(str(p), grey)
    return ds
