"""Hostile and unlucky input on the write side (issue 19): the figures of
docs/results/hostile_input.md.

Run from the repository root::

    python benchmarks/hostile_cases.py [--only KIND] [--verbose]

Runs every case of ``tests/hostile_cases.py`` (names used as paths, links followed on write,
inputs that ended in a traceback), each in a fresh folder beside a sentinel folder of files
that are not multieye's, and prints per case the exit status and the verdict, then per class:

- cases tried;
- clean outcomes: the expected exit status, exactly one ``multieye: error:`` line naming what
  is wrong (for a refusal), no traceback, and the case's own check (files where they belong);
- data lost: cases in which a file that is not multieye's (in the sentinel folder) was
  written, removed or replaced;
- changed outside OUT: cases in which anything outside ``OUT`` changed (the sentinel, or a
  lock, staging or backup name beside ``OUT`` left behind or taken over), or ``OUT``
  changed although the command was refused.

To see the same cases against another version of multieye, put its sources first on the
path: ``PYTHONPATH=/path/to/other/src python benchmarks/hostile_cases.py``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hostile_cases import CASES, make_template, make_work, run_case  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("names", "links", "tracebacks"))
    parser.add_argument("--verbose", action="store_true", help="print each problem in full")
    args = parser.parse_args()
    import multieye

    print(f"multieye from {Path(multieye.__file__).parent}")
    cases = [c for c in CASES if args.only in (None, c.kind)]
    tried, clean, lost, changed = Counter(), Counter(), Counter(), Counter()
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp:
        template = make_template(Path(tmp) / "template")
        for k, case in enumerate(cases):
            work = make_work(Path(tmp) / f"case{k}", template)
            try:
                o = run_case(case, work)
            except Exception as exc:        # a case the version under test cannot even run
                print(f"{case.kind:10s} {'?':>4s}  {'ERROR':5s}  {case.name}: {exc!r}")
                tried[case.kind] += 1
                continue
            tried[case.kind] += 1
            clean[case.kind] += o.clean
            changed[case.kind] += bool(o.outside_changed) or (
                o.code == 2 and o.out_changed and not case.out_may_change)
            lost[case.kind] += any(p.startswith("sentinel/") for p in o.outside_changed)
            verdict = "clean" if o.clean else "FAIL"
            print(f"{case.kind:10s} {o.code:4d}  {verdict:5s}  {case.name}"
                  + ("" if o.clean else f": {o.problem if args.verbose else o.problem[:110]}"))
    print()
    print(f"{'class':12s} {'tried':>6s} {'clean':>6s} {'data lost':>10s} "
          f"{'changed outside OUT':>20s}")
    for kind in ("names", "links", "tracebacks"):
        if tried[kind]:
            print(f"{kind:12s} {tried[kind]:6d} {clean[kind]:6d} {lost[kind]:10d} "
                  f"{changed[kind]:20d}")
    print(f"{'all':12s} {sum(tried.values()):6d} {sum(clean.values()):6d} "
          f"{sum(lost.values()):10d} {sum(changed.values()):20d}")


if __name__ == "__main__":
    main()
