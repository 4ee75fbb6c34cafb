"""HTML pieces of the report: number cells, tables and embedded figures.

Shared by :mod:`multieye.outputs.report` (the page) and :mod:`multieye.outputs.report_cameras`
(its per-camera and diagnostics sections).  Every text is escaped here; callers pass plain
strings (captions are HTML).
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterable, Sequence
from html import escape

import numpy as np

__all__ = ["num", "value_text", "table", "figure"]


def num(x, fmt: str, scale: float = 1.0) -> str:
    """A number cell, or an en dash for a missing or non-finite value."""
    if x is None:
        return "–"
    x = float(x) * scale
    return format(x, fmt) if np.isfinite(x) else "–"


def value_text(v) -> str:
    """A free-form diagnostics value as text."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return format(v, ".4g")
    if isinstance(v, str):
        return v
    return json.dumps(v, separators=(", ", ": "))


def table(header: Sequence[str], rows: Iterable[Sequence[str]], *, left: int = 1,
           classes: Sequence[Sequence[str]] | None = None,
           groups: Sequence[tuple[str, int]] = ()) -> str:
    """An HTML table of escaped text cells; the first ``left`` columns are left-aligned.

    ``groups`` adds a first header row of ``(label, number of columns)`` spans (an empty
    label leaves those columns ungrouped), so that sub-headers can stay short.
    """
    def cls(i, extra=""):
        names = " ".join(n for n in ("l" if i < left else "", extra) if n)
        return f' class="{names}"' if names else ""

    top = ""
    if groups:
        cells, i = [], 0
        for label, span in groups:
            cells.append(f'<th colspan="{span}"{cls(i, "group" if label else "")}>'
                         f"{escape(label)}</th>")
            i += span
        top = f"<tr>{''.join(cells)}</tr>"
    head = "".join(f"<th{cls(i)}>{escape(h)}</th>" for i, h in enumerate(header))
    # each cell names its column (group and header), shown before it where the table is
    # laid out as one block per row (narrow screens, the report's style)
    labels = list(header)
    if groups:
        i = 0
        for label, span in groups:
            for k in range(i, i + span):
                if label and k < len(labels):
                    labels[k] = f"{label}: {labels[k]}"
            i += span
    body = []
    for r, row in enumerate(rows):
        extra = classes[r] if classes is not None else [""] * len(row)
        body.append("<tr>" + "".join(
            f'<td{cls(i, extra[i])} data-label="{escape(labels[i] if i < len(labels) else "")}">'
            f"{escape(str(c))}</td>" for i, c in enumerate(row)) + "</tr>")
    return (f'<div class="wrap"><table><thead>{top}<tr>{head}</tr></thead>'
            f'<tbody>{"".join(body)}</tbody></table></div>')


def figure(data: bytes, alt: str, caption: str, name: str) -> str:
    """A figure embedded as a base64 PNG or JPEG (told by its first bytes), its caption
    (HTML) and where its file is."""
    mime = "image/jpeg" if data[:3] == b"\xff\xd8\xff" else "image/png"
    encoded = base64.b64encode(data).decode("ascii")
    return (f'<figure><img src="data:{mime};base64,{encoded}" alt="{escape(alt)}">'
            f"<figcaption>{caption} <span class=\"note\">(also <code>figures/{escape(name)}"
            "</code>)</span></figcaption></figure>")
