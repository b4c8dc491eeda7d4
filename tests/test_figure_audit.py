"""The figure audit (report/figure_audit.py) catches what it is for: each check is fed a
figure with the fault and one without, and only the faulty one is refused."""
from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from report import figure_audit as audit  # noqa: E402
from report.figures import legend_outside, save_figure, solver_style  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _axes(size=(6, 4)):
    fig, ax = plt.subplots(figsize=size)
    return fig, ax


def test_a_title_must_name_its_own_scene_and_no_other():
    scenes = {"circle_square", "cube_sphere", "circle_square_matched"}
    assert audit.scene_problems("circle_square: time per solver", "circle_square", scenes) == []
    assert audit.scene_problems("time per solver", "cube_sphere", scenes) == [
        "the title does not name the scene cube_sphere"]
    assert audit.scene_problems("cube sphere beside circle_square", "cube_sphere", scenes) == [
        "the title names another scene, circle_square"]
    # a scene whose name holds another's is not 'another scene'
    assert audit.scene_problems("circle_square_matched: map", "circle_square_matched",
                                scenes) == []


def test_a_legend_entry_without_data_is_refused():
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2], "o-", color="C0", label="drawn")
    ax.legend(handles=[*ax.get_legend_handles_labels()[0],
                       Line2D([], [], ls="none", marker="s", color="C1", label="never drawn")])
    assert audit.undrawn_entries(fig) == [
        "legend entry 'never drawn' of 'untitled panel' is not drawn"]


def test_a_line_style_at_one_size_is_not_drawn():
    """One point per series: its marker is drawn, the line its entry shows is not."""
    fig, ax = _axes()
    ax.plot([3.0], [1.0], "o--", color="C0", label="one size, dashed")
    ax.plot([3.0], [2.0], "s", color="C1", label="one size, a point")
    ax.legend()
    assert audit.undrawn_entries(fig) == [
        "legend entry 'one size, dashed' of 'untitled panel' is not drawn"]


def test_a_key_entry_stands_for_any_colour_but_its_own_encoding():
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2], "o", color="C0", mfc="none")
    grey = audit.KEY_GREY
    ax.legend(handles=[Line2D([], [], color=grey, marker="o", ls="none", label="filled"),
                       Line2D([], [], color=grey, marker="o", ls="none", mfc="none",
                              label="hollow")])
    assert audit.undrawn_entries(fig) == ["legend entry 'filled' of 'untitled panel' is not drawn"]


def test_a_solver_whose_points_are_all_hollow_keeps_its_legend_entry():
    """The fill is the key's to explain (verified or not): a solver never verified is still
    in the legend by its colour and marker, and a hollow entry still needs hollow points."""
    from report.figures import solver_legend
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2], ls="none", color=solver_style("osqp")["color"],
            marker=solver_style("osqp")["marker"])
    ax.plot([1, 2], [2, 3], ls="none", color=solver_style("ecos")["color"],
            marker=solver_style("ecos")["marker"], mfc="none")
    solver_legend(ax, ["ecos", "osqp"])
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["ecos", "osqp", "verified converged", "not verified"]
    assert audit.undrawn_entries(fig) == []
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2], "o", color="C0")
    ax.legend(handles=[Line2D([], [], color="C0", marker="o", ls="none", mfc="none",
                              label="hollow, in a colour")])
    assert audit.undrawn_entries(fig) == [
        "legend entry 'hollow, in a colour' of 'untitled panel' is not drawn"]


def test_a_colour_key_lists_only_the_colours_the_image_shows():
    from matplotlib.colors import ListedColormap
    fig, ax = _axes()
    ax.imshow([[0, 0], [0, 0]], cmap=ListedColormap(["#2ca02c", "#d62728"]), vmin=0, vmax=1)
    ax.legend(handles=[Patch(color="#2ca02c", label="converged"),
                       Patch(color="#d62728", label="failed")])
    assert audit.undrawn_entries(fig) == ["legend entry 'failed' of 'untitled panel' is not drawn"]


def test_nan_in_a_title_label_or_legend_is_refused():
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2], label=f"slope {np.nan:.2f}")
    ax.set_title("time per solver, NaN here")
    ax.set_xlabel("nanometre scale")              # a word that starts with nan is fine
    ax.legend()
    assert sorted(audit.nan_texts(fig)) == ["text reads nan: 'slope nan'",
                                            "text reads nan: 'time per solver, NaN here'"]


def test_a_legend_over_the_data_is_refused_and_one_beside_it_passes():
    x = np.linspace(0, 1, 200)
    fig, ax = _axes()
    ax.plot(x, 0.5 + 0.4 * np.sin(12 * x), "o", ms=2, label="data everywhere")
    ax.legend(loc="center")
    found = audit.covering_legends(fig)
    assert len(found) == 1 and "covers data of 'untitled panel'" in found[0]
    fig, ax = _axes()
    ax.plot(x, 0.5 + 0.4 * np.sin(12 * x), "o", ms=2, label="data everywhere")
    legend_outside(ax)
    assert audit.covering_legends(fig) == []


def test_the_legends_check_sees_the_figure_as_it_is_now():
    """The check draws only a figure changed since its last draw (save_figure has just
    drawn it): a legend moved over the data after a draw is found, and one moved off it
    is cleared."""
    x = np.linspace(0, 1, 200)
    fig, ax = _axes()
    ax.plot(x, 0.5 + 0.4 * np.sin(12 * x), "o", ms=2, label="data everywhere")
    legend_outside(ax)
    fig.canvas.draw()
    assert not fig.stale and audit.covering_legends(fig) == []
    ax.legend(loc="center")
    assert fig.stale and len(audit.covering_legends(fig)) == 1
    assert not fig.stale
    legend_outside(ax)
    assert audit.covering_legends(fig) == []


def test_a_legend_over_a_line_between_its_points_is_refused():
    """A line's segments are data too: two far points joined under the legend."""
    fig, ax = _axes()
    ax.plot([0, 1], [0.5, 0.5], "-", label="a long line")
    ax.set_xlim(-0.1, 1.1)
    ax.legend(loc="center")
    assert audit.covering_legends(fig)


def test_a_panel_needs_its_axis_labels_and_a_time_its_unit():
    fig, ax = _axes()
    ax.plot([1, 2], [1, 2])
    ax.set_xlabel("nodes N")
    assert audit.label_problems(fig) == ["'untitled panel' has no y label"]
    ax.set_ylabel("wall time")
    assert audit.label_problems(fig) == ["axis label 'wall time': a time without its unit"]
    ax.set_ylabel("wall time [s]")
    assert audit.label_problems(fig) == []
    ax.set_ylabel("time within this factor of the best")        # a pure number
    assert audit.label_problems(fig) == []


def test_colours_need_a_labelled_colourbar_or_a_key():
    fig, ax = _axes()
    im = ax.imshow(np.arange(4.0).reshape(2, 2))
    ax.set(xlabel="x", ylabel="y", title="field")
    assert audit.label_problems(fig) == ["'field': colours without a colourbar or key"]
    bar = fig.colorbar(im, ax=ax)
    assert audit.label_problems(fig) == ["a colourbar without a label"]
    bar.set_label("pressure")
    assert audit.label_problems(fig) == []


def test_a_solver_must_wear_its_own_colour_and_marker():
    fig, ax = _axes()
    scs = solver_style("scs")
    ax.plot([1, 2], [1, 2], "-", color=solver_style("osqp")["color"], marker=scs["marker"],
            label="osqp")
    ax.legend()
    styles = audit.solver_entries(fig)
    assert styles == {"osqp": {"color": solver_style("osqp")["color"], "marker": scs["marker"]}}
    assert len(audit.solver_problems(styles)) == 1
    own = {"osqp": {"color": solver_style("osqp")["color"],
                    "marker": solver_style("osqp")["marker"]}}
    assert audit.solver_problems(own) == []


def test_across_figures_one_style_per_solver_and_none_shared():
    a = {"osqp": {"color": "#8c564b", "marker": "P"}}
    b = {"osqp": {"color": "#8c564b", "marker": "*"}, "scs": {"color": "#8c564b", "marker": "P"}}
    found = audit.style_conflicts({"a.png": a, "b.png": b})
    assert any("osqp has 2 styles" in f for f in found)
    assert any("osqp and scs share the style" in f for f in found)
    assert audit.style_conflicts({"a.png": a, "c.png": a}) == []
    # a (sides, style, angle) marker read back from a figure's JSON metadata is a list:
    # the same marker, compared and reported like the others
    tuple_marker = solver_style("tresca_exact")
    assert isinstance(tuple_marker["marker"], tuple)
    read_back = {"tresca_exact": json.loads(json.dumps(tuple_marker))}
    assert isinstance(read_back["tresca_exact"]["marker"], list)
    assert audit.style_conflicts({"a.png": read_back, "b.png": {"tresca_exact": tuple_marker},
                                  "c.png": a}) == []
    assert audit.solver_problems(read_back) == []
    clash = {"osqp": {"color": tuple_marker["color"], "marker": tuple_marker["marker"]}}
    assert any("share the style" in f
               for f in audit.style_conflicts({"a.png": read_back, "d.png": clash}))


def test_an_image_too_wide_for_its_fonts_is_refused():
    assert audit.legibility_problem(900, 130, 7) is None
    assert audit.legibility_problem(1400, 130, 7) is None          # scaled to 950 px: 8.6 px
    assert "3.8 px" in audit.legibility_problem(2744, 130, 6)      # the hard cases at 14 solvers


def test_the_saved_png_carries_every_problem_back(tmp_path):
    """save_figure records the figure's problems; png_problems reads them with the width."""
    fig, ax = plt.subplots(figsize=(24, 4))
    ax.plot([1, 2], [1, np.nan], "o--", label="nan")
    ax.set_title("no scene named")
    ax.legend(fontsize=6)
    path = tmp_path / "results" / "cube_sphere" / "solver_times.png"
    path.parent.mkdir(parents=True)
    save_figure(fig, str(path), scene="cube_sphere")
    found = audit.png_problems(path, {"cube_sphere", "circle_square"})
    assert any("is not drawn" in f for f in found)                  # one point: no line
    assert any("reads nan" in f for f in found)
    assert any("no x label" in f for f in found)
    assert any("in the 950 px frame" in f for f in found)           # 24 in wide, 6 pt
    text, width = audit.png_text(path)
    assert json.loads(text["contactbench:problems"]) and width > 2000
    bare = tmp_path / "bare.png"
    plt.figure().savefig(bare)
    assert "no audit record" in audit.png_problems(bare)[0]


def _one_size_runs():
    import pandas as pd
    return pd.DataFrame({"solver": ["osqp", "scs", "linear_floor"], "preset": "mid",
                         "level": 0, "n": 8000, "total_time": [0.3, 0.9, 0.05],
                         "energy_error": [1e-7, 1e-9, np.nan],
                         "status": ["converged", "max_iter", "converged"]})


def test_the_solver_figures_at_one_size_draw_points_and_say_so(tmp_path):
    """One size: the times figure is a dot chart (no line, the floor a vertical line), the
    work-precision's title no longer promises curves, and both pass the audit."""
    from report import solver_comparison as sc
    runs = _one_size_runs().assign(scene_problem="circle_square")
    out = tmp_path / "results" / "circle_square"
    times, work = out / "solver_times.png", out / "solver_error_vs_time.png"
    sc.times_figure(sc.times_frame(runs), "circle_square", str(times))
    sc.work_precision_figure(sc.work_frame(runs), "circle_square", str(work))
    for path in (times, work):
        assert audit.png_problems(path, {"circle_square"}) == [], path
    assert "at one size, N = 8,000" in audit.png_text(times)[0]["Title"]
    assert "one point per solver" in audit.png_text(work)[0]["Title"]


def test_a_legend_of_several_panels_is_the_figures_and_lists_only_what_they_draw():
    """solver_legend over several panels: a figure legend, its entries checked against
    every panel; an encoding no panel draws (hollow: not verified) is left out."""
    from report.figures import solver_legend
    fig, (a, b) = plt.subplots(1, 2)
    osqp = solver_style("osqp")
    b.plot([1, 2], [1, 2], osqp["marker"], color=osqp["color"], ls="none")
    solver_legend(a, ["osqp"], axes=[a, b])
    assert a.get_legend() is None and len(fig.legends) == 1
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["osqp", "verified converged"]
    assert audit.undrawn_entries(fig) == []


def test_a_lone_point_is_drawn_without_a_line_and_its_entry_passes():
    from report.figures import drawable
    assert drawable("s--", [1.0, np.nan], [2.0, 3.0]) == "s"
    assert drawable("o-.", [1.0, 2.0], [2.0, 3.0]) == "o-."
    fig, ax = _axes()
    ax.plot([3.0], [1.0], drawable("o--", [3.0], [1.0]), label="one size")
    ax.legend()
    assert audit.undrawn_entries(fig) == []
