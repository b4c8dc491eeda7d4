"""Rate fits and the Ch. 8 claims table on data with known answers."""
import numpy as np
import pandas as pd

from report.augmented_projection import claims, read_thesis, thesis_table
from report.rates import fitted_slope as slope
from report.rates import fitted_rate, rate_table


def test_fitted_rate_recovers_exact_powers_over_the_finest_levels():
    h = 1 / 2 ** np.arange(1, 7)
    err = 3 * h ** 2
    err[:2] *= 10  # pre-asymptotic coarse levels do not enter
    assert abs(fitted_rate(h, err, last=3) - 2) < 1e-12
    assert np.isnan(fitted_rate(h, 1e-14 * np.ones_like(h)))  # round-off: no rate


def test_rate_table_groups():
    h = 1 / 2 ** np.arange(1, 5)
    df = pd.DataFrame({"case": "c", "variant": np.repeat(["a", "b"], 4), "level": np.tile(range(4), 2),
                       "h": np.tile(h, 2), "err": np.concatenate([h, h ** 2])})
    rates = rate_table(df, ["case", "variant"], {"err": "rate"})
    np.testing.assert_allclose(rates["rate"], [1, 2])
    assert list(rates["levels"]) == ["1..3", "1..3"]


def _study(t_of_n, n_outer, kappa, fast=None):
    """Synthetic study: alg84 at 4x the floor; ``fast`` adds a config ``face_cg`` at that
    multiple of the floor."""
    N = np.array([4e3, 1.6e4, 6.4e4, 2.56e5])
    rows = [{"level": i + 1, "N": n, "NC": 33 * 2 ** i, "n": 2 * n, "config": "alg84",
             "n_outer": n_outer[i], "n_inner_mean": 3.0, "t_setup": 0.0, "t_solve": t_of_n(n),
             "t_proj": 0.01, "kappa_S": kappa[i], "energy_error": 1e-3, "kkt_max": 1e-3,
             "stop_8_25": True, "status": "converged", "n_outer_1e-03": n_outer[i],
             "t_to_target": 2 * t_of_n(n)} for i, n in enumerate(N)]
    rows += [{"level": i + 1, "N": n, "config": "amg_pcg_gmg", "t_to_target": t_of_n(n) / 2}
             for i, n in enumerate(N)]
    if fast is not None:
        rows += [{"level": i + 1, "N": n, "config": "face_cg", "t_to_target": fast * t_of_n(n) / 2}
                 for i, n in enumerate(N)]
    # the semismooth Newton row is faster than everything, but no configuration of Alg. 8.4
    rows += [{"level": i + 1, "N": n, "config": "semismooth_newton", "t_to_target": t_of_n(n) / 2,
              "t_setup": 0.0, "t_solve": t_of_n(n) / 2} for i, n in enumerate(N)]
    return pd.DataFrame(rows)


def test_claims_pass_and_fail_on_synthetic_studies():
    good = claims(_study(lambda n: 1e-5 * n, [8, 8, 8, 8], [34, 68, 136, 272],
                         fast=1.8)).set_index("claim")
    assert list(good["pass"].iloc[:3]) == [True, True, True]
    assert abs(good["measured"].iloc[2] - 1.0) < 1e-12       # slope of t ~ N
    assert abs(good["measured"].iloc[3] - 4.0) < 1e-12       # 2 t / (t / 2)
    assert abs(good["measured"].iloc[4] - 1.8) < 1e-12       # the best variant
    # no published bar: the ratios to a linear solve are reported figures, never judged
    assert good["pass"].iloc[3:5].isna().all() and list(good["bar"].iloc[3:5]) == ["-", "-"]
    alone = claims(_study(lambda n: 1e-5 * n, [8, 8, 8, 8], [34, 68, 136, 272]))
    assert alone["pass"].iloc[3:5].isna().all()
    assert "alg84" in alone["parameters"].iloc[4] and abs(alone["measured"].iloc[4] - 4.0) < 1e-12
    bad = claims(_study(lambda n: 1e-8 * n ** 1.5, [8, 9, 12, 20], [34, 68, 136, 272]))
    assert not bad["pass"].iloc[0] and not bad["pass"].iloc[2]
    assert abs(bad["measured"].iloc[2] - 1.5) < 1e-12
    assert abs(slope([1, 2, 4], [1, 4, 16]) - 2) < 1e-12


def test_table_9_1_sits_beside_the_thesis():
    thesis = read_thesis("reference/table_9_1.csv")
    assert list(thesis["nodes"]) == [4226, 16642, 66050, 263170]
    t = thesis_table(_study(lambda n: 1e-5 * n, [8] * 4, [34, 68, 136, 272]), thesis)
    assert list(t["thesis_n_outer_1e-03"]) == [19, 19, 20, 21]
    assert list(t["n_outer_1e-03"]) == [8] * 4 and list(t["NC"]) == [33, 66, 132, 264]
    t3 = thesis_table(_study(lambda n: 1e-5 * n, [8] * 4, [34, 68, 136, 272]),
                      read_thesis("reference/table_9_3.csv"))
    assert list(t3["thesis_n_outer_1e-02"][:3]) == [107, 112, 115]
    assert t3["thesis_nodes"].isna().iloc[3]              # the thesis has no fourth level


def test_claims_ignore_runs_that_stopped_short():
    study = _study(lambda n: 1e-5 * n, [8, 8, 8, 400], [34, 68, 136, 272])
    study.loc[(study.config == "alg84") & (study.level == 4), "stop_8_25"] = False
    got = claims(study).set_index("claim")["measured"]
    assert got.iloc[0] == 0.0  # growth measured over the levels that did reach (8.25)


def test_hertz_claims_ask_for_a_falling_deviation_only_above_the_model_floor():
    import pandas as pd

    from report.contact_solution import HERTZ_MODEL_FLOOR, claims as hertz_claims

    def table(devs):
        return pd.DataFrame({"level": range(len(devs)), "a_over_h": 10.0,
                             "dev_a_moment": devs, "dev_p0_moment": devs})

    def passes(devs):
        return hertz_claims(table(devs))["pass"].tolist()

    assert passes([0.04, 0.02]) == [True, True, True, True]           # falls
    assert passes([0.008, -0.010]) == [True, True, True, True]        # at the floor
    assert passes([0.02, 0.03]) == [True, False, True, False]         # rises above it
    assert passes([0.04, 0.06]) == [False, False, False, False]       # beyond the bar
    assert HERTZ_MODEL_FLOOR < 0.05


def test_one_solver_style_everywhere_and_every_registered_solver_told_apart():
    from report.figures import solver_order, solver_style
    from solvers.interface import external_solvers, solvers
    names = sorted(set(solvers()) - set(external_solvers()))
    styles = [(solver_style(n)["color"], solver_style(n)["marker"]) for n in names]
    assert len(set(styles)) == len(names)                     # colour and marker tell apart
    assert len({c for c, _ in styles}) == len(names)          # and so do colours alone
    assert solver_style("osqp") == solver_style("osqp")
    assert list(solver_order()[:len(names)]) == names
    assert solver_style("not_a_solver") == solver_style("not_a_solver")   # hashed, stable


def test_a_figure_names_its_scene_from_its_path():
    from report.figures import scene_of
    assert scene_of("results/cube_sphere/solver_times.png") == "cube_sphere"
    assert scene_of("/tmp/x/results/roll_stack/roll_stack_sag.png") == "roll_stack"
    assert scene_of("results/hard_cases/hard_cases.png") is None
    assert scene_of("results/solver_summary/performance_profiles.png") is None


def _audit(path):
    from report.figure_audit import png_text
    return png_text(path)[0]


def test_saved_figures_record_their_titles_data_and_empty_panels(tmp_path):
    import matplotlib.pyplot as plt

    from report.figures import nothing_to_draw, save_figure
    fig, (a, b) = plt.subplots(1, 2)
    a.loglog([1e3, 4e3, 6e3], [1, 2, 3], "o-")
    b.set_title("nothing here")
    path = tmp_path / "results" / "cube_sphere" / "solver_times.png"
    path.parent.mkdir(parents=True)
    save_figure(fig, str(path))
    meta = _audit(path)
    assert meta["contactbench:scene"] == "cube_sphere" and "cube_sphere" in meta["Title"]
    assert meta["contactbench:data_artists"] == "1" and meta["contactbench:empty_panels"] == "1"
    empty = tmp_path / "empty.png"
    nothing_to_draw(str(empty), "Work-precision, family x", "no run has an energy error")
    meta = _audit(empty)
    assert meta["contactbench:nothing_to_draw"] == "no run has an energy error"
    assert meta["contactbench:data_artists"] == "0"


def test_log_axes_get_no_crowded_minor_labels():
    import matplotlib.pyplot as plt

    from report.figures import sparse_log_ticks
    fig, ax = plt.subplots()
    ax.loglog([3.5e3, 6.5e3], [1, 2])
    sparse_log_ticks(ax, "x")
    fig.canvas.draw()
    minor = [t.get_text() for t in ax.get_xticklabels(minor=True) if t.get_text()]
    assert minor == []
    major = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    assert 1 <= len(major) <= 4
    plt.close(fig)
