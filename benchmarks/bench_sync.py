"""What syncing a run's files to disk costs: one by one as written, or together (issue 32).

Run from the repository root::

    python benchmarks/bench_sync.py OUT [--repeats 10] [--into FOLDER]

Writes every file of OUT (a ``multieye calibrate`` output folder: calibration.json,
details.json, camchain.yaml, report.html, figures/, ...) into a fresh folder with
:func:`multieye.io.atomic.write_bytes_atomic`, as a run writes its staging folder: each file
synced as it is written (before: a sync of the file and of its folder per file, one after
the other), or inside :func:`multieye.io.atomic.synced_together` (every file synced at once
after the last write, then the folders); the two in turn, ``--repeats`` times each.  Prints
the wall seconds of each way (median, range).  The folder (default: beside OUT, on its file
system) is removed after each write.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import time
from pathlib import Path

from multieye.io.atomic import make_folder, synced_together, write_bytes_atomic


def write_all(files: dict[Path, bytes], folder: Path, together: bool) -> float:
    """Seconds to write ``files`` (relative paths) into the new ``folder`` and sync them."""
    start = time.perf_counter()
    os.mkdir(folder)
    with synced_together(folder) if together else _nothing():
        for rel, data in files.items():
            if len(rel.parts) > 1:
                make_folder(folder / rel.parent)
            write_bytes_atomic(folder / rel, data)
    seconds = time.perf_counter() - start
    shutil.rmtree(folder)
    return seconds


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--into", type=Path, default=None)
    args = ap.parse_args(argv)
    files = {p.relative_to(args.out): p.read_bytes()
             for p in sorted(args.out.rglob("*")) if p.is_file()}
    into = args.into or args.out.parent
    times: dict[str, list[float]] = {"one by one": [], "together": []}
    for k in range(args.repeats):
        for way in (list(times) if k % 2 == 0 else list(times)[::-1]):
            folder = into / f".bench_sync_{os.getpid()}_{k}"
            times[way].append(write_all(files, folder, way == "together"))
    size = sum(map(len, files.values())) / 1e6
    print(f"{len(files)} files, {size:.1f} MB, into {into}; load {os.getloadavg()[0]:.1f}")
    for way, t in times.items():
        print(f"  {way:10s}: median {statistics.median(t):.3f} s (range {min(t):.3f}-"
              f"{max(t):.3f}), {len(t)} writes")


if __name__ == "__main__":
    main()
