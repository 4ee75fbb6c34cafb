"""Tasks on a job's results run by the detection's workers (issue 21: a camera's lens start
and its poses on the pool, as soon as its images are in), and the fork server started early."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from proc_tree import group_processes, needs_proc
from batch_images import BOARD, CAMERA, check, render_image_files

from multieye.imaging import batch
from multieye.imaging.batch import ImageJob, detect_jobs_then


#: four rendered views, a corrupt file, a blank image and a missing path, with the truth
image_files = pytest.fixture(scope="module", name="image_files")(render_image_files)


@pytest.mark.parametrize("processes", [1, 2])
def test_each_jobs_task_gets_exactly_that_jobs_results(image_files, processes):
    order, _ = image_files
    paths = tuple(str(p) for p in order)
    # four jobs: two parts, an empty one, the whole list (16 images: chunks of 2, so job
    # boundaries fall inside chunks)
    jobs = [ImageJob(paths[:3], BOARD, CAMERA), ImageJob(paths[3:], BOARD, CAMERA),
            ImageJob((), BOARD, CAMERA), ImageJob(paths, BOARD, CAMERA)]
    results, done = detect_jobs_then(jobs, {0: len, 1: len, 2: len, 3: len},
                                     processes=processes, progress=False)
    assert [len(r) for r in results] == [3, len(paths) - 3, 0, len(paths)]
    check(results[0] + results[1], image_files)
    check(results[3], image_files)
    assert done == {0: 3, 1: len(paths) - 3, 2: 0, 3: len(paths)}
    # a task only where asked
    results, done = detect_jobs_then(jobs[:2], {1: len}, processes=processes, progress=False)
    assert done == {1: len(paths) - 3}


SPY = textwrap.dedent("""
    import sys
    from multiprocessing import forkserver
    from multieye.imaging import workers

    started = workers.prestart_workers

    def spy(processes, **kw):
        running = started(processes, **kw)
        print("prestart", running, "multieye.pipeline" in sys.modules, "cv2" in sys.modules,
              forkserver._forkserver._forkserver_pid, *kw.get("preload", ()), file=sys.stderr)
        return running

    workers.prestart_workers = spy

    if __name__ == "__main__":
        from multieye.cli import main
        try:
            main(sys.argv[1:], standalone_mode=False)
        finally:
            print("server", forkserver._forkserver._forkserver_pid, file=sys.stderr)
""")


def test_calibrate_starts_the_fork_server_before_importing_the_pipeline(tmp_path):
    """The fork server's imports overlap the main process's: started before
    ``multieye.pipeline`` and OpenCV are imported, and the one the detection's workers come
    from."""
    from small_dataset import render_small

    ds = tmp_path / "ds"
    render_small(ds, images_per_camera=6)
    script = tmp_path / "spy.py"
    script.write_text(SPY)
    run = subprocess.run([sys.executable, str(script), "calibrate", str(ds), "-o",
                          str(tmp_path / "out"), "--processes", "2"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    lines = [line.split() for line in run.stderr.splitlines()
             if line.startswith(("prestart", "server"))]
    (_, running, imported, opencv, pid, *preload), (_, after) = lines
    assert (running, imported, opencv) == ("True", "False", "False")
    assert preload == ["multieye.outputs.figure_workers"]   # it imports the figure modules later
    assert pid == after != "None"        # not started again for the detection; still running
    # with one process there are no workers: nothing is started
    one = subprocess.run([sys.executable, str(script), "calibrate", str(ds), "-o",
                          str(tmp_path / "out1"), "--processes", "1"],
                         capture_output=True, text=True, timeout=300)
    assert one.returncode == 0, one.stderr
    assert "prestart False False False None multieye.outputs.figure_workers" in one.stderr


@needs_proc
def test_an_error_before_detection_leaves_no_early_fork_server_behind(tmp_path):
    """The fork server started before the pipeline's imports is stopped and collected when
    the run fails before detection (exit 2: a rig.yaml the reader refuses)."""
    from small_dataset import render_small

    ds = tmp_path / "ds"
    render_small(ds, images_per_camera=4)
    (ds / "rig.yaml").write_text((ds / "rig.yaml").read_text() + "\nunknown_key: 1\n")
    proc = subprocess.Popen([sys.executable, "-m", "multieye", "calibrate", str(ds), "-o",
                             str(tmp_path / "out"), "--processes", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    _, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 2, stderr
    assert len(stderr.strip().splitlines()) == 1 and "unknown_key" in stderr, stderr
    assert group_processes(proc.pid) == {}
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("n_items", "n_workers"), [(400, 2), (1000, 2), (400, 8), (16, 2),
                                                    (3, 2), (7, 4)])
def test_chunks_shrink_towards_the_end_so_the_workers_end_together(n_items, n_workers):
    """Guided chunks (issue 21): every item once, in order; no chunk larger than the first,
    none larger than the one before; the last ones a few images, so that no worker waits a
    whole chunk for the others (equal chunks of 50 left a core idle 0.1 s on average)."""
    items = list(range(n_items))
    chunks = batch._chunks(items, n_workers)
    assert [i for c in chunks for i in c] == items
    sizes = [len(c) for c in chunks]
    assert all(a >= b for a, b in zip(sizes, sizes[1:]))
    assert sizes[0] <= max(1, -(-n_items // (n_workers * batch._CHUNKS_PER_WORKER)))
    assert sizes[-1] <= batch._MIN_CHUNK
    if n_items >= 400:       # long runs: the last chunks far smaller than the first
        assert max(sizes[-n_workers:]) <= max(batch._MIN_CHUNK, sizes[0] // 8)
        assert len(chunks) <= 8 * n_workers * batch._CHUNKS_PER_WORKER
