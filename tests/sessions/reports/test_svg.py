"""The report's SVG charts: well-formed, scaled into the plot box, gaps kept, labels escaped."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from gaitscope.sessions.reports.svg import Line, _ticks, line_chart

NS = "{http://www.w3.org/2000/svg}"


def test_chart_is_valid_svg_with_gaps_and_escaped_labels() -> None:
    svg = line_chart([Line([0, 1, 2, 3, 4], [0.0, 1.0, None, 3.0, 4.0], label="a <b> & c")], x_label="x", y_label="y")
    root = ET.fromstring(svg)
    lines = root.findall(f"{NS}polyline")
    assert len(lines) == 2  # the gap splits the line
    texts = [t.text for t in root.iter(f"{NS}text")]
    assert "a <b> & c" in texts and "x" in texts and "y" in texts
    for pl in lines:
        for pt in pl.get("points", "").split():
            x, y = map(float, pt.split(","))
            assert 52 <= x <= 480 - 150 and 10 <= y <= 220 - 40


def test_empty_chart_says_so() -> None:
    assert "no data" in line_chart([Line([0, 1], [None, None])], x_label="x", y_label="y")


def test_ticks_are_round() -> None:
    assert _ticks(0, 100) == [0, 20, 40, 60, 80, 100]
    assert _ticks(-0.9, 0.2) == [-0.75, -0.5, -0.25, 0.0]
