"""Engines (multieye.imaging.engines): results in input order on the local pool and on a
local Dask cluster, detection tasks on Dask, and clear errors."""

from __future__ import annotations

import functools
import time
from pathlib import Path

import pytest
from proc_tree import working_descendants

from multieye.core.errors import InputError
from multieye.imaging.engines import DaskEngine, open_engine


def _square_plus(x, y=0):
    return x * x + y


def _marked_nap(folder: str, k: int) -> int:
    Path(folder, f"{k}.started").touch()
    time.sleep(0.4)
    return k


def test_an_interrupted_local_engine_ends_its_workers_and_starts_nothing_more(tmp_path):
    """A Ctrl-C (or SIGTERM's Stopped) in the block that uses the engine ends its workers and
    cancels what is queued: calibrate-many went on with every dataset, after saying it stopped,
    since the engine shut its pool down as after success."""
    before = working_descendants()
    with pytest.raises(KeyboardInterrupt):
        with open_engine("local", processes=2) as eng:
            # held in a name, as calibrate_many holds it: not closed when the loop raises
            done = enumerate(eng.map(_marked_nap, [(str(tmp_path), k) for k in range(12)],
                                     star=True, chunksize=1))
            for _ in done:
                raise KeyboardInterrupt
    started = len(list(tmp_path.glob("*.started")))
    assert not working_descendants() - before
    time.sleep(0.5)                                 # nothing starts once the block has left
    assert len(list(tmp_path.glob("*.started"))) == started < 12


@pytest.mark.parametrize("processes", [1, 2])
def test_local_engine_keeps_the_order(processes):
    with open_engine("local", processes=processes) as eng:
        assert list(eng.map(_square_plus, range(50))) == [x * x for x in range(50)]
        assert list(eng.map(_square_plus, [(x, 1) for x in range(9)], star=True)) == \
            [x * x + 1 for x in range(9)]


def test_dask_engine_on_a_threaded_local_cluster_keeps_the_order():
    pytest.importorskip("distributed", reason="the distributed extra is not installed")
    with DaskEngine(workers=2, processes=False) as eng:
        assert list(eng.map(_square_plus, range(100), chunksize=7)) == [x * x for x in range(100)]
        done = dict(eng.submit_each(_square_plus, [(x, 2) for x in range(5)], star=True))
        assert done == {x: x * x + 2 for x in range(5)}


def test_detection_tasks_on_dask_match_the_local_pool(tmp_path):
    """The images of a rendered camera detected on a Dask cluster of 2 worker processes give
    the same corners as in this process."""
    pytest.importorskip("distributed", reason="the distributed extra is not installed")
    import numpy as np
    from small_dataset import render_small

    from multieye.imaging.batch import process_image
    from multieye.imaging.targets import target_from_spec
    from multieye.io import load_rig, read_camera_intrinsics

    render_small(tmp_path / "d", images_per_camera=4)
    rig = load_rig(tmp_path / "d" / "rig.yaml")
    target = target_from_spec(rig.target.as_dict())
    intr = read_camera_intrinsics(rig.cameras["cam0"])
    paths = sorted(str(p) for p in (tmp_path / "d" / "cam0").glob("*.png"))
    work = functools.partial(process_image, target=target, intrinsics=intr)
    with open_engine("local", processes=1) as eng:
        here = list(eng.map(work, paths))
    with open_engine("dask", workers=2) as eng:
        there = list(eng.map(work, paths, chunksize=1))
    assert [r.path for r in there] == paths
    assert sum(r.ok for r in here) >= 3
    for a, b in zip(here, there):
        assert a.ok == b.ok
        if a.ok:
            np.testing.assert_allclose(a.detection.image_points, b.detection.image_points)


def test_unknown_engine_and_scheduler_without_dask_are_refused():
    with pytest.raises(InputError, match="engine must be one of"):
        open_engine("spark")
    with pytest.raises(InputError, match="needs the dask engine"):
        open_engine("local", scheduler="tcp://127.0.0.1:8786")
