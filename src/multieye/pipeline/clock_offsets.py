"""Each camera's clock offset against the motion capture, estimated from its own views.

``--time-offset auto`` (docs/conventions.md, section 4: ``time_offset_s`` = motion-capture
clock minus camera clock) runs :func:`multieye.estimate.clock.estimate_offset` on each camera
with motion capture: its views' board poses against the motion capture.  With one target
the joint refinement then estimates the offsets again with the rest
(:mod:`multieye.pipeline.run`).  With several boards (:mod:`multieye.pipeline.overlap_mocap`)
a camera's offset comes from the views of the board it sees most (every board stands still,
so each is a hand-eye problem ``A X = Y B`` of its own, and the offset search needs only one)
and is then held: the joint problem of the views, the rig's motion and the motion capture
pairs every image at it, and the offset's standard deviation is the search's
(:attr:`multieye.estimate.clock.ClockOffset.std_s`: the measurement noise only).

Synopsis
--------
>>> off = estimated_offset(problem, problem.cameras["cam0"])     # doctest: +SKIP
>>> problem, clocks = with_clock_offsets(problem)                # doctest: +SKIP
"""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import numpy as np

from multieye.core.errors import CalibrationError
from multieye.estimate.clock import ClockOffset, estimate_offset
from multieye.estimate.clock_residuals import shared_clocks
from multieye.pipeline.camera_data import CameraData
from multieye.pipeline.problem import Problem, make_problem

__all__ = ["CLOCK_MIN_SCORE", "estimated_offset", "with_clock_offsets"]

#: Smallest angular-speed correlation at which an automatic clock offset is trusted.
CLOCK_MIN_SCORE = 0.5


def estimated_offset(problem: Problem, d: CameraData, observations=None) -> ClockOffset:
    """The clock offset of camera ``d`` from its views (``observations``: those of one board;
    default every view), checked.

    Raises
    ------
    CalibrationError
        The search failed, the angular speeds of camera and motion capture correlate below
        :data:`CLOCK_MIN_SCORE`, the loop residuals have no minimum near the correlation's
        peak (:attr:`~multieye.estimate.clock.ClockOffset.note`), or the best offset lies at
        the edge of the search range (``--max-time-offset``); each names the camera and what
        to do.
    """
    obs = d.observations if observations is None else observations
    search = (-problem.options.max_time_offset, problem.options.max_time_offset)
    try:
        est = estimate_offset(np.array([o.stamp for o in obs]),
                              np.stack([o.T_cam_target for o in obs]),
                              d.mocap.stamps, d.mocap.T, setup=problem.setup, search_s=search)
    except CalibrationError as exc:
        raise CalibrationError(f"camera {d.name}: clock offset could not be estimated: {exc}; "
                               "give --time-offset SECONDS or time_offset in rig.yaml") from None
    edge = 0.02 * (search[1] - search[0])
    if not est.score >= CLOCK_MIN_SCORE:
        raise CalibrationError(
            f"camera {d.name}: the clock offset cannot be estimated (angular speeds of camera "
            f"and motion capture correlate at {est.score:.2f}, below {CLOCK_MIN_SCORE}): move "
            "the target faster and less uniformly, or give --time-offset SECONDS")
    if (min(est.coarse_offset_s, est.offset_s) < search[0] + edge
            or max(est.coarse_offset_s, est.offset_s) > search[1] - edge):
        peak = ("" if not search[0] + edge <= est.offset_s <= search[1] - edge else
                f"; the angular speeds correlate best at {est.coarse_offset_s:+.3f} s")
        raise CalibrationError(
            f"camera {d.name}: the best clock offset ({est.offset_s:+.3f} s{peak}) is at the edge of "
            f"the search range {search[0]:+.3g}..{search[1]:+.3g} s, so the true one is "
            "probably outside it; widen the search (--max-time-offset SECONDS) or give "
            "--time-offset SECONDS (or time_offset in rig.yaml)")
    if est.note:
        raise CalibrationError(f"camera {d.name}: the clock offset cannot be estimated: "
                               f"{est.note}; give --time-offset SECONDS or time_offset in "
                               "rig.yaml")
    return est


def with_clock_offsets(problem: Problem) -> tuple[Problem, dict[str, ClockOffset], tuple[str, ...]]:
    """The problem with every camera's ``time_offset`` the one to pair with, the offsets
    estimated by camera, and notes (several boards: module docstring).

    ``time_offset="rig"``: rig.yaml's, unchanged; a number: that many seconds for every camera
    with a clock; ``"auto"``: each camera with motion capture and a clock (not paired by
    name) estimated from the views of the board it sees most.  Cameras triggered together
    (:func:`multieye.estimate.clock_residuals.shared_clocks`: equal stamps for at least half
    of each one's images; one motion capture) are stamped by one clock, as in the one-board
    path: they get one offset, the mean of their own estimates weighted by the inverse
    variances, with the smallest of their standard deviations (their searches share the
    motion capture's noise, so not the combined one); a note says so.  A camera whose own
    views cannot be timed (too few of one board) takes the offset of a timed camera with an
    equal stamp for at least half of its images (triggered with it), with a note.  The problem is
    made again (:func:`multieye.pipeline.problem.make_problem`), its instants at the new
    offsets; the options keep their ``time_offset``, so the record says how the offsets
    came.

    Raises
    ------
    CalibrationError
        As :func:`estimated_offset`, for a camera on a clock of its own or whose clock no
        camera could time.
    """
    opts = problem.options.time_offset
    if opts == "rig":
        return problem, {}, ()
    clocked = [n for n, d in problem.cameras.items() if not d.by_name and d.mocap is not None]
    if opts != "auto":
        return _made_again(problem, dict.fromkeys(clocked, float(opts))), {}, ()
    own, failed = {}, {}
    for n in clocked:
        d = problem.cameras[n]
        board = Counter(o.target for o in d.observations).most_common(1)[0][0]
        try:
            own[n] = estimated_offset(problem, d, [o for o in d.observations
                                                   if o.target == board])
        except CalibrationError as exc:
            failed[n] = exc
    clocks, notes = dict(own), []
    for group in _one_clock(problem, clocked):
        timed = [own[n] for n in group if n in own]
        if not timed:
            continue
        w = np.array([1.0 / max(c.std_s, 1e-9) ** 2 for c in timed])
        shared = replace(timed[0], offset_s=float(np.dot(w, [c.offset_s for c in timed])
                                                  / w.sum()),
                         std_s=float(min(c.std_s for c in timed)))
        clocks |= dict.fromkeys(group, shared)
        notes.append(f"{', '.join(group)}: image stamps equal (triggered together), so one "
                     f"clock: one time offset ({shared.offset_s:+.4f} s) from "
                     f"{', '.join(n for n in group if n in own)}")
    for n, exc in failed.items():
        if n in clocks:
            continue
        source = _triggered_with(problem, n, clocks)
        if source is None:
            raise exc
        clocks[n] = clocks[source]
        notes.append(f"camera {n}: too few views to time its clock "
                     f"({str(exc).split(': ', 2)[-1].split('; give')[0]}); its image stamps "
                     f"are {source}'s (triggered together), so its offset "
                     f"({clocks[n].offset_s:+.4f} s)")
    return _made_again(problem, {n: c.offset_s for n, c in clocks.items()}), clocks, tuple(notes)


def _one_clock(problem: Problem, clocked: list[str]) -> list[list[str]]:
    """Groups of cameras on one clock: triggered together and on one motion capture."""
    cams = [problem.cameras[n] for n in clocked]
    groups = shared_clocks([[o.stamp for o in d.observations] for d in cams],
                           [(d.mocap.stamps, d.mocap.T) for d in cams])
    return [[clocked[k] for k in group] for group in groups]


def _same_mocap(a: CameraData, b: CameraData) -> bool:
    """Whether two cameras pair with one motion capture (one object, or equal samples)."""
    return a.mocap is b.mocap or (np.array_equal(a.mocap.stamps, b.mocap.stamps)
                                  and np.array_equal(a.mocap.T, b.mocap.T))


def _triggered_with(problem: Problem, name: str, clocks: dict) -> str | None:
    """The timed camera (in ``clocks``) on the same motion capture that has an equal stamp for
    at least half of camera ``name``'s images, the most such first; None when none has."""
    d = problem.cameras[name]
    mine = np.array([o.stamp for o in d.observations], dtype=np.float64)
    best, count = None, 0
    for m in clocks:
        other = problem.cameras[m]
        if not _same_mocap(other, d):
            continue
        k = int(np.isin(mine, [o.stamp for o in other.observations]).sum())
        if 2 * k >= mine.size and k > count:
            best, count = m, k
    return best


def _made_again(problem: Problem, offsets: dict[str, float]) -> Problem:
    """The problem with these cameras' clock offsets, its instants grouped again at them."""
    cameras = {n: replace(d, time_offset=float(offsets[n])) if n in offsets else d
               for n, d in problem.cameras.items()}
    return make_problem(problem.rig, cameras, problem.options, problem.model)
