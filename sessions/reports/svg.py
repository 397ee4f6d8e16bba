"""Small line charts as SVG text, for the PDF report (no plotting library: a few polylines and ticks)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from html import escape
from typing import Final

__all__ = ["PALETTE", "Line", "line_chart"]

PALETTE: Final = ("#0b5cad", "#c2410c", "#1d7a3a", "#a21caf", "#4b5563", "#b45309", "#0e7490", "#be123c")
_FONT: Final = "Libertinus Serif, New Computer Modern, serif"


@dataclass(frozen=True)
class Line:
    """One series: ``y`` over ``x`` (None: a gap), with its legend label."""

    x: Sequence[float]
    y: Sequence[float | None]
    label: str = ""
    color: str = PALETTE[0]
    width: float = 1.5
    opacity: float = 1.0


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """About ``n`` round tick values covering ``[lo, hi]``."""
    span = hi - lo
    step = 10 ** math.floor(math.log10(span / n))
    for m in (1, 2, 2.5, 5, 10):
        if span / (step * m) <= n:
            step *= m
            break
    first = math.ceil(lo / step) * step
    return [round(first + k * step, 10) for k in range(int((hi - first) / step + 1e-9) + 1)]


def _fmt(v: float) -> str:
    return f"{v:g}" if abs(v) >= 0.01 or v == 0 else f"{v:.1e}"


def line_chart(
    lines: Sequence[Line], *, x_label: str, y_label: str, width: int = 480, height: int = 220, legend: bool = True
) -> str:
    """An SVG document drawing ``lines`` with axes, ticks, axis labels and (optionally) a legend."""
    xs = [x for ln in lines for x, y in zip(ln.x, ln.y, strict=True) if y is not None and math.isfinite(y)]
    ys = [y for ln in lines for y in ln.y if y is not None and math.isfinite(y)]
    left, right, top, bottom = 52, 12, 10, 40
    labelled = [ln for ln in lines if ln.label]
    if legend and labelled:
        right = 150
    pw, ph = width - left - right, height - top - bottom
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" '
        f'font-family="{_FONT}" font-size="11">',
        f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="white" stroke="#9ca3af"/>',
    ]
    if not xs:
        out.append(f'<text x="{left + pw / 2}" y="{top + ph / 2}" text-anchor="middle">no data</text></svg>')
        return "\n".join(out)
    x0, x1 = min(xs), max(xs)
    y0, y1 = min(ys), max(ys)
    if x1 == x0:
        x0, x1 = x0 - 1, x1 + 1
    if y1 == y0:
        y0, y1 = y0 - 1, y1 + 1
    pad = 0.05 * (y1 - y0)
    y0, y1 = y0 - pad, y1 + pad

    def px(x: float) -> float:
        return left + (x - x0) / (x1 - x0) * pw

    def py(y: float) -> float:
        return top + (1 - (y - y0) / (y1 - y0)) * ph

    for t in _ticks(x0, x1):
        out.append(f'<line x1="{px(t):.1f}" y1="{top + ph}" x2="{px(t):.1f}" y2="{top + ph + 4}" stroke="#374151"/>')
        out.append(f'<text x="{px(t):.1f}" y="{top + ph + 15}" text-anchor="middle">{_fmt(t)}</text>')
    for t in _ticks(y0, y1):
        out.append(f'<line x1="{left}" y1="{py(t):.1f}" x2="{left + pw}" y2="{py(t):.1f}" stroke="#e5e7eb"/>')
        out.append(f'<text x="{left - 5}" y="{py(t) + 4:.1f}" text-anchor="end">{_fmt(t)}</text>')
    out.append(f'<text x="{left + pw / 2}" y="{height - 6}" text-anchor="middle">{escape(x_label)}</text>')
    out.append(
        f'<text x="12" y="{top + ph / 2}" text-anchor="middle" transform="rotate(-90 12 {top + ph / 2})">'
        f"{escape(y_label)}</text>"
    )
    for ln in lines:
        runs: list[list[str]] = [[]]
        for x, y in zip(ln.x, ln.y, strict=True):
            if y is None or not math.isfinite(y):
                runs.append([])
            else:
                runs[-1].append(f"{px(x):.1f},{py(y):.1f}")
        for run in runs:
            if len(run) > 1:
                out.append(
                    f'<polyline points="{" ".join(run)}" fill="none" stroke="{ln.color}" '
                    f'stroke-width="{ln.width}" stroke-opacity="{ln.opacity}"/>'
                )
            elif len(run) == 1:
                cx, cy = run[0].split(",")
                out.append(f'<circle cx="{cx}" cy="{cy}" r="1.6" fill="{ln.color}" fill-opacity="{ln.opacity}"/>')
    if legend:
        for k, ln in enumerate(labelled[:12]):
            y = top + 8 + 15 * k
            out.append(f'<line x1="{width - right + 8}" y1="{y}" x2="{width - right + 26}" y2="{y}" '
                       f'stroke="{ln.color}" stroke-width="2.5"/>')  # fmt: skip
            out.append(f'<text x="{width - right + 30}" y="{y + 4}">{escape(ln.label)}</text>')
    out.append("</svg>")
    return "\n".join(out)
