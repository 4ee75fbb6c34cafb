"""What the solvers accept, known without importing them: the closed-form methods' names and
the fewest measurements a camera needs.

Options are checked against these before any work (:mod:`multieye.pipeline.options`), while
the solvers themselves (SciPy's sparse and dense linear algebra) are imported later, during
the detection (issue 21).  :mod:`multieye.solvers.registry` maps the same names to the
solvers; ``tests/solvers`` checks that the two agree.
"""

from __future__ import annotations

__all__ = ["JOINT_METHOD_NAMES", "SINGLE_METHOD_NAMES", "METHODS", "MIN_MEASUREMENTS"]

#: The methods that solve every camera at once, with one ``Y``.
JOINT_METHOD_NAMES: tuple[str, ...] = ("joint", "wang2022")

#: The methods that solve each camera on its own (``Y`` combined afterwards).
SINGLE_METHOD_NAMES: tuple[str, ...] = ("shah", "li", "tabb-c1", "tabb-c2")

#: Every method name accepted by :func:`multieye.solvers.solve`.
METHODS: tuple[str, ...] = JOINT_METHOD_NAMES + SINGLE_METHOD_NAMES

#: Fewest measurements a camera needs.
MIN_MEASUREMENTS = 3
