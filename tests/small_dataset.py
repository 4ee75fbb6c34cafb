"""A small rendered dataset (2 cameras x 8 images, 640 x 480): the whole image pipeline fast."""

from __future__ import annotations

from pathlib import Path

from multieye.sim.dataset import DatasetSpec, render_dataset


def render_small(folder: Path, *, seed: int = 2, images_per_camera: int = 8):
    """Render into ``folder`` (created); returns the ground truth."""
    spec = DatasetSpec(n_cameras=2, images_per_camera=images_per_camera, width=640, height=480,
                       processes=1)
    return render_dataset(folder, spec, seed=seed)
