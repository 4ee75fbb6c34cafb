"""Figures of the synthetic experiments (the only module of ``experiments`` that imports
matplotlib); the same kind of module as :mod:`multieye.outputs.figures`, which draws the
calibration report's.

matplotlib is imported when a figure is drawn, not when this module is imported, and only its
Agg canvas is used (no pyplot, no global backend switch), so drawing works without a display
and leaves an interactive session's backend alone.

>>> from multieye.experiments.figures import sweep_png
>>> png = sweep_png("noise level f (%)", [("rotation error (deg)", {"joint": ([0, 5], [0, 1])})])
>>> png[:4] == b"\\x89PNG"
True
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from io import BytesIO

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Curves", "sweep_png"]

#: One panel's curves: method name -> (x values, y values).
Curves = Mapping[str, tuple[ArrayLike, ArrayLike]]

_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")
_LINESTYLES = ("-", "--", "-.", ":")


def sweep_png(x_label: str, panels: Sequence[tuple[str, Curves]], *, title: str = "",
              log_x: bool = False, log_y: bool = False, dpi: int = 120) -> bytes:
    """Draw one panel per metric, one curve per method, and return the PNG bytes.

    Every method keeps the same colour, marker and line style in every panel, and methods
    listed first are drawn on top, so that curves which coincide (two solvers with the same
    optimum) stay distinguishable by their markers; a single legend is drawn under the panels.

    Parameters
    ----------
    x_label : str
        Label of the swept parameter (shared by all panels).
    panels : sequence of (str, Curves)
        Y-axis label and the curves of each panel; non-finite y values leave gaps.
    title : str
        Figure title.
    log_x, log_y : bool
        Logarithmic axes. With at most 12 distinct x values, the x axis is ticked at them.
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    bytes
        The PNG file's content (the caller writes it, atomically).
    """
    # matplotlib loads in about a second: only when a figure is drawn
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy, see above)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy, see above)
    from matplotlib.ticker import NullLocator  # noqa: PLC0415 (heavy, see above)

    n = len(panels)
    cols = 1 if n == 1 else 2
    rows = -(-n // cols)
    methods = list(dict.fromkeys(name for _, curves in panels for name in curves))
    legend_cols = min(len(methods), 3 * cols) or 1
    legend_height = 0.2 + 0.28 * -(-len(methods) // legend_cols)  # inches, under the panels
    height = 3.6 * rows + legend_height
    fig = Figure(figsize=(6.0 if cols == 1 else 10.4, height), dpi=dpi)
    FigureCanvasAgg(fig)
    colours = [f"C{k % 10}" for k in range(len(methods))]
    handles = {}
    for k, (y_label, curves) in enumerate(panels):
        ax = fig.add_subplot(rows, cols, k + 1)
        for name, (x, y) in curves.items():
            i = methods.index(name)
            (line,) = ax.plot(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                              color=colours[i], marker=_MARKERS[i % len(_MARKERS)],
                              linestyle=_LINESTYLES[i % len(_LINESTYLES)], markersize=5,
                              linewidth=1.4, markerfacecolor="none", label=name,
                              zorder=3 + len(methods) - i)  # first-listed method on top
            handles.setdefault(name, line)
        if log_x:
            ax.set_xscale("log")
        xs = np.unique(np.concatenate([np.ravel(np.asarray(x, dtype=float))
                                       for x, _ in curves.values()]))
        if 0 < xs.size <= 12:  # a sweep over a few values: tick exactly those
            ax.set_xticks(xs, [f"{v:g}" for v in xs])
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xlabel(x_label)
        ax.set_ylabel(y_label)
        if log_y:
            ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.35)
    fig.legend([handles[m] for m in methods], methods, loc="lower center",
               ncol=legend_cols, frameon=False)
    if title:
        fig.suptitle(title)
    fig.tight_layout(rect=(0.0, legend_height / height, 1.0, 1.0))
    buffer = BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()
