"""Which images the dry run (:mod:`multieye.pipeline.dry_run`) decodes: an evenly spaced
sample, and more of the rest while the sample shows the target in too few of them.

A recording where the target is in a tiny minority of the images (most frames without the
board, unreadable, of another size) is calibrated: the selection chooses again from the rest
until its budget of usable images is met (:func:`multieye.pipeline.selection.with_refills`).
The dry run's first sample of such a camera may hold no image with the target, and said
that calibrating would fail; so it samples on, evenly over the images not yet tried, until
:data:`~multieye.solvers.methods.MIN_MEASUREMENTS` show the target, every image was tried, or
the camera's budget of :data:`BUDGET_PER_SAMPLE` times the sample was decoded (a camera none of
whose 10,000 images shows the board is not decoded whole; :func:`budget_note` says so).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from multieye.solvers.methods import MIN_MEASUREMENTS

__all__ = ["BUDGET_PER_SAMPLE", "budget_note", "sample_budget", "evenly_spaced", "sampled_on",
           "shortfall"]

#: Sampling on decodes at most this many times ``sample`` images of a camera (200 by default).
BUDGET_PER_SAMPLE = 10


def sample_budget(sample: int) -> int:
    """The most images of one camera the dry run decodes, first sample included."""
    return BUDGET_PER_SAMPLE * int(sample)


def evenly_spaced(n: int, k: int) -> list[int]:
    """At most ``k`` evenly spaced indices of ``range(n)``, first and last included."""
    if n <= k:
        return list(range(n))
    return sorted(set(np.linspace(0, n - 1, k).round().astype(int).tolist()))


def sampled_on(n: int, sampled: Sequence[int], results: Sequence,
               detect: Callable[[list[int]], list], budget: int) -> tuple[list[int], list]:
    """``sampled`` (indices of ``range(n)``) and their ``results``, with more sampled from
    the rest while fewer than MIN_MEASUREMENTS results show the target (``reason`` None)
    and fewer than ``budget`` images were tried.

    Each round takes, evenly spaced over the indices not yet tried, as many as still wanted
    divided by the share found so far (Laplace's estimate: ``(found + 1) / (tried + 2)``), as
    the selection's refills do, so that a camera with the target in half its images needs
    one small round and one with none is searched whole.

    Parameters
    ----------
    n : int
        Images listed.
    sampled : sequence of int
        Indices already detected.
    results : sequence of ImageResult
        Their results, in the same order.
    detect : callable
        ``detect(indices) -> (done, results)`` of more images: the indices it could read
        (a video's frame may not decode) and their results.
    budget : int
        At most this many indices are tried in all (:func:`sample_budget`).

    Returns
    -------
    sampled, results : list
        In listed order.
    """
    idx, res = list(sampled), list(results)
    tried = set(idx)
    found = sum(r.reason is None for r in res)
    while found < MIN_MEASUREMENTS and len(tried) < min(n, budget):
        rest = [i for i in range(n) if i not in tried]
        ask = min(len(rest), budget - len(tried),
                  math.ceil((MIN_MEASUREMENTS - found) * (len(tried) + 2) / (found + 1)))
        pick = [rest[k] for k in evenly_spaced(len(rest), ask)]
        done, more = detect(pick)
        tried.update(pick)
        idx += list(done)
        res += list(more)
        found += sum(r.reason is None for r in more)
    order = np.argsort(idx, kind="stable")
    return [idx[k] for k in order], [res[k] for k in order]


def budget_note(found: int, listed: int, sample: int) -> str:
    """``" (sampling stopped at ...)"`` when a camera's sampling on ended at its budget with
    fewer than MIN_MEASUREMENTS images showing the target (more listed than the budget: it
    would otherwise have tried them all), else ``""``."""
    budget = sample_budget(sample)
    if found >= MIN_MEASUREMENTS or listed <= budget:
        return ""
    return (f" (sampling stopped at its budget of {budget} images per camera, "
            f"{BUDGET_PER_SAMPLE} x --sample: {listed - budget} of {listed} images not searched)")


def shortfall(usable: int, found: int, sampled: int, expected: int, listed: int, *,
              decided: bool = False) -> tuple[str, bool] | None:
    """Why calibrating would fail for lack of usable images, and whether the sample decides
    it; None when enough would remain.

    Parameters
    ----------
    usable, found, sampled : int
        Sampled images usable, with the target found, and decoded.
    expected, listed : int
        Usable images extrapolated to the camera's ``listed`` images.
    decided : bool
        The images searched decide it whatever the rest hold (another board than rig.yaml's
        was found in them: the target section is wrong).

    Returns
    -------
    (str, bool) or None
        The reason, and True when it is decided: every image was searched, or enough showed
        the target (what is short is then the motion capture); False when the sampling
        stopped at its budget (:func:`sample_budget`) with fewer than ``MIN_MEASUREMENTS``
        found, since the images not searched may hold the target (calibrating searches them
        all: :func:`multieye.pipeline.selection.with_refills`), also where the few found
        extrapolate to enough (2 of 20 searched is no evidence of 30 of 302).
    """
    if found < MIN_MEASUREMENTS and sampled < listed and not decided:
        # the budget stopped the search: an estimate from 1 or 2 hits (2 of 20 searched, so
        # "about 30 of 302") says nothing; only searching the rest does
        return (f"fewer than {MIN_MEASUREMENTS} usable images among the {sampled} searched "
                f"({usable} usable); {listed - sampled} of its {listed} images were not "
                "searched (the check's budget): calibrating may fail, and searches them all "
                f"(--sample {math.ceil(listed / BUDGET_PER_SAMPLE)} searches them here)", False)
    if expected >= MIN_MEASUREMENTS and usable > 0:
        return None
    return (f"fewer than {MIN_MEASUREMENTS} usable images would remain ({usable} of {sampled} "
            f"sampled usable, about {expected} of {listed} in all)", True)
