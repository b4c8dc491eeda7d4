"""The interactive Vega-Lite charts beside the PNGs (report/charts.py): the PNGs' colours
and shapes, inline data, a spec that names a missing field refused, a page that carries
its scripts (no network)."""
from __future__ import annotations

import pandas as pd
from matplotlib.colors import to_hex

from report import charts
from report.figures import solver_style


def _runs() -> pd.DataFrame:
    return pd.DataFrame({"solver": ["pdas", "pdas", "osqp", "osqp"],
                         "preset": ["low", "mid", "low", "mid"],
                         "n": [100, 400, 100, 400], "total_time": [0.1, 0.5, 0.2, float("nan")],
                         "verified": [True, True, False, True]})


def test_a_chart_has_the_figures_colours_and_inline_data():
    spec = charts.solver_chart(_runs(), ("n", "N", True), ("total_time", "time", True), "t",
                               tooltip=("preset",), line_by=("preset",), dash="preset",
                               filled="verified")
    assert charts.spec_problems(spec) == []
    line, points = spec["layer"]
    colour = line["encoding"]["color"]["scale"]
    assert colour["domain"] == ["osqp", "pdas"]
    assert colour["range"] == [to_hex(solver_style(s)["color"]) for s in ("osqp", "pdas")]
    floor = charts.solver_scales(["linear_floor"])[0]["range"]
    assert floor == ["#000000"]                     # matplotlib's "k", as CSS understands it
    shape = points["encoding"]["shape"]["scale"]["range"]
    assert shape == [charts.SHAPES[solver_style(s)["marker"]] for s in ("osqp", "pdas")]
    assert line["encoding"]["strokeDash"]["scale"]["domain"] == ["low", "mid"]
    values = spec["data"]["values"]
    assert len(values) == 4 and values[3]["total_time"] is None     # NaN: no point
    assert values[2]["verified"] is False and isinstance(values[0]["n"], int)


def test_a_spec_naming_a_missing_field_or_without_data_is_refused():
    spec = charts.solver_chart(_runs(), ("n", "N", True), ("total_time", "time", True), "t",
                               facet="preset")
    assert charts.spec_problems(spec) == []
    spec["spec"]["layer"][0]["encoding"]["y"]["field"] = "wall"
    assert "['wall']" in charts.spec_problems(spec)[0]
    assert charts.spec_problems({**spec, "data": {"values": []}}) == ["data: not inline, or empty"]
    assert "$schema" in charts.spec_problems({**spec, "$schema": "v3"})[0]


def test_a_page_carries_its_scripts_and_specs(tmp_path):
    spec = charts.solver_chart(_runs(), ("n", "N", True), ("total_time", "time", True),
                               "times </script> here")
    path = tmp_path / "results" / "s" / "solver_times.html"
    charts.write_page(str(path), [("note", spec)], "title")
    text = path.read_text()
    assert "<script src" not in text and "<link" not in text      # nothing fetched
    assert charts.page_scripts(text) == {s: charts.script_text(s) for s in charts.SCRIPTS}
    assert len(text) < 1_000_000        # framed as a data: URL, it must stay under 2 MB
    assert charts.page_specs(text) == [spec]                       # </script> escaped
    assert charts.chart_path("results/c/solver_times.png") == "results/c/solver_times.html"
    assert charts.charted("results/circle_square/solver_times.png")
    assert charts.charted("results/solver_summary/performance_profiles.png")
    assert not charts.charted("results/circle_square/solver_error_vs_time.png")


def test_every_solver_has_its_own_shape_in_the_charts():
    """A marker is one Vega-Lite shape, no two markers the same (a plus and a star are
    not both a cross), so that no two solvers share a shape in a chart."""
    from report.figures import MARKERS, solver_order
    assert set(MARKERS) <= set(charts.SHAPES)
    shapes = [charts.SHAPES[m] for m in MARKERS]
    assert len(set(shapes)) == len(shapes)
    colours, marks = charts.solver_scales(solver_order())
    assert len(set(zip(colours["range"], marks["range"]))) == len(solver_order())
    osqp, scs = (charts.SHAPES[solver_style(s)["marker"]] for s in ("osqp", "scs"))
    assert osqp != scs
    # a plus and a star look alike at a few pixels: their colours are far apart
    from matplotlib.colors import to_rgb
    rgb = [to_rgb(solver_style(s)["color"]) for s in ("osqp", "scs")]
    assert sum((a - b) ** 2 for a, b in zip(*rgb)) ** 0.5 > 0.3
