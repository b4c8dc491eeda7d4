"""Every workflow script's and report builder's main() on small levels into a temporary
directory, and the Snakemake workflow: dry run, lint, config validation, scenes by config."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from workflows.studies import STUDIES, ConfigError, all_targets, check_config, load_config

ROOT = Path(__file__).resolve().parent.parent
SNAKEMAKE = Path(sys.executable).parent / "snakemake"
SCENE = ["--problem", "circle_square"]


def run(module: str, *argv: str) -> None:
    __import__(module, fromlist=["main"]).main(list(argv))


@pytest.fixture(scope="module")
def contact(tmp_path_factory):
    out = tmp_path_factory.mktemp("contact")
    for level in ("0", "1"):
        run("workflows.studies.contact_solution.run", *SCENE, "--level", level, "--outdir", str(out))
    return out


def test_contact_solution_and_its_report(contact, tmp_path):
    for level in (0, 1):
        c = pd.read_csv(contact / f"contact_L{level}.csv")
        assert {"x0", "x1", "s0", "p", "pressure", "gap", "active"} <= set(c.columns)
        assert (contact / f"fields_L{level}.vtu").stat().st_size > 0
    rows = [str(contact / f"hertz_L{k}.csv") for k in (0, 1)]
    run("report.contact_solution", "hertz", "--inputs", *rows, "--out", str(tmp_path / "hertz.csv"))
    h = pd.read_csv(tmp_path / "hertz.csv")
    assert list(h["level"]) == [0, 1] and (h["status"] == "converged").all()
    assert (h[["dev_a_moment", "dev_p0_moment"]].abs() < 0.1).all().all()
    run("report.contact_solution", "fields", "--vtu", str(contact / "fields_L1.vtu"),
        "--out", str(tmp_path / "fields.png"))
    run("report.contact_solution", "pressure", "--contacts", *[str(contact / f"contact_L{k}.csv")
                                                      for k in (0, 1)],
        "--hertz", *rows, "--out", str(tmp_path / "pressure.png"))
    run("report.contact_solution", "surface", "--vtu", str(contact / "fields_L1.vtu"),
        "--out", str(tmp_path / "surface.png"))
    for name in ("fields.png", "pressure.png", "surface.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_contact_solution_in_3d(tmp_path):
    """The same script and builders on the cube-sphere scene (3D cut, point-contact Hertz)."""
    for level in ("0", "1"):
        run("workflows.studies.contact_solution.run", "--problem", "cube_sphere", "--level", level,
            "--outdir", str(tmp_path))
    c = pd.read_csv(tmp_path / "contact_L1.csv")
    assert {"x0", "x1", "x2", "s0", "s1"} <= set(c.columns) and len(c) == 81
    rows = [str(tmp_path / f"hertz_L{k}.csv") for k in (0, 1)]
    run("report.contact_solution", "hertz", "--inputs", *rows, "--out", str(tmp_path / "hertz.csv"))
    h = pd.read_csv(tmp_path / "hertz.csv")
    assert (h["status"] == "converged").all() and (h["a_hertz"] > 0.2).all()
    run("report.contact_solution", "pressure", "--contacts", *[str(tmp_path / f"contact_L{k}.csv")
                                                      for k in (0, 1)],
        "--hertz", *rows, "--out", str(tmp_path / "pressure.png"))
    for what in ("fields", "surface"):
        run("report.contact_solution", what, "--vtu", str(tmp_path / "fields_L1.vtu"),
            "--out", str(tmp_path / f"{what}.png"))
    for name in ("fields.png", "pressure.png", "surface.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_solver_comparison_skips_by_the_coarser_levels(tmp_path):
    """``--coarser`` results make a run that timed out there, or whose fitted
    time predicts more than the limit here, a ``skipped`` row with the reason."""
    from workflows.io import write_csv
    n = {0: 2000, 1: 8000}
    for level in (0, 1):
        write_csv(tmp_path / f"L{level}.csv", pd.DataFrame({
            "level": level, "n": n[level], "solver": ["osqp", "piqp"], "preset": "mid",
            "status": ["converged", "time_limit" if level else "converged"],
            "total_time": [0.5 * 16 ** level, 1.0], "message": ""}))
    run("workflows.studies.solver_comparison.run", *SCENE, "--level", "2", "--presets", "mid",
        "--solvers", "osqp", "piqp", "pdas", "--time-limit", "60",
        "--coarser", str(tmp_path / "L0.csv"), str(tmp_path / "L1.csv"),
        "--out", str(tmp_path / "L2.csv"))
    t = pd.read_csv(tmp_path / "L2.csv").set_index(["solver", "preset"])
    assert t.loc[("osqp", "mid"), "status"] == "skipped"      # exponent 2: 8 s x ~17 > 60 s
    assert re.fullmatch(r"skipped: predicted 1\d\d s > time limit 60 s \(time exponent 2\.00 in n "
                        r"over levels 0-1\)", t.loc[("osqp", "mid"), "message"])
    assert t.loc[("piqp", "mid"), "message"] == "skipped: timed out at level 1"
    assert t.loc[("pdas", "mid"), "status"] == "converged"


def test_solver_comparison_and_its_report(tmp_path):
    run("workflows.studies.solver_comparison.run", *SCENE, "--level", "0", "--presets", "mid",
        "--time-limit", "60", "--out", str(tmp_path / "solvers_L0.csv"))
    t = pd.read_csv(tmp_path / "solvers_L0.csv")
    from solvers.interface import solvers
    assert set(t["solver"]) == set(solvers()) | {"linear_floor"}   # every solver and the floor
    assert (t.loc[t.preset == "reference", "solver"] == "pdas").all()
    assert {"status", "kkt_max", "energy_error", "peak_mem_mb", "wall_time"} <= set(t.columns)
    ref = t[t.preset == "reference"]
    assert len(ref) == 1 and ref["kkt_max"].iloc[0] < 1e-10
    ok = t[(t.status == "converged") & (t.solver != "linear_floor")]
    assert (ok["kkt_max"] <= ok["tol"]).all() and (ok["energy_error"] < 1e-3).all()
    assert set(t.loc[t.solver == "linear_floor", "preset"]) == {"mid"}     # the floor row
    outs = {k: str(tmp_path / f"{k}.{'csv' if k in ('table', 'presets', 'costs') else 'png'}")
            for k in ("table", "presets", "times", "work", "costs")}
    outs["charts"] = str(tmp_path / "times.html")
    run("report.solver_comparison", "--inputs", str(tmp_path / "solvers_L0.csv"),
        *[a for k, v in outs.items() for a in (f"--{k}", v)])
    assert len(pd.read_csv(outs["table"])) == len(t)
    presets = pd.read_csv(outs["presets"])
    assert set(presets["solver"]) == set(solvers()) and presets["options"].notna().all()
    costs = pd.read_csv(outs["costs"])
    assert set(costs["solver"]) == set(solvers()) - {"pdas"}      # the reference is its own row
    skipped = set(t.loc[t.status == "skipped", "solver"])
    assert {"tresca_exact", "highs"} <= skipped    # friction only; above HiGHS's size limit
    ran = ~costs["solver"].isin(skipped)
    assert (costs.loc[ran, "floor_ratio_L0"] > 0).all()
    assert costs.loc[~ran, "floor_ratio_L0"].isna().all()      # a refusal is no time
    from report.charts import page_specs, spec_problems
    times, work = page_specs(Path(outs["charts"]).read_text())
    assert spec_problems(times) == [] and spec_problems(work) == []
    # every run but the reference and the skips (a skip's time is its refusal)
    assert len(times["data"]["values"]) == ((t.preset != "reference")
                                            & (t.status != "skipped")).sum()


def test_augmented_projection_study_and_its_report(tmp_path):
    study = tmp_path / "study.csv"
    run("workflows.studies.augmented_projection.run", *SCENE, "--levels", "0", "1",
        "--configs", "alg84", "nested_face_cg", "--kappa-exact", "--time-limit", "60",
        "--out", str(study))
    s = pd.read_csv(study)
    assert set(s["config"]) == {"reference", "alg84", "nested_face_cg", "semismooth_newton",
                                "tnnmg", "tnnmg_nested", "amg_pcg_gmg", "amg_pcg_sa"}
    tnnmg = s[s.config.str.startswith("tnnmg")]
    assert (tnnmg["status"] == "converged").all() and (tnnmg["energy_error"] <= 1e-6).all()
    assert (tnnmg["n_to_target"] > 0).all() and (tnnmg["t_to_target"] > tnnmg["t_setup"]).all()
    # the timed rows whose ratio the claims judge are the median of three runs
    timed = s[s.config.str.startswith(("tnnmg", "amg_pcg"))]
    assert (timed["timing_repeats"] == 3).all()
    assert ((timed["t_to_target_min"] <= timed["t_to_target"])
            & (timed["t_to_target"] <= timed["t_to_target_max"])).all()
    nested = tnnmg[tnnmg.config == "tnnmg_nested"].set_index("level")["t_coarse_levels"]
    assert nested.notna().all() and (nested >= 0).all()
    # memory: TNNMG from zero and the floor, per level; the input both hold is the same
    mem = s[s["mem_peak_mb"].notna()].set_index(["config", "level"])
    assert set(mem.index.get_level_values(0)) == {"tnnmg", "amg_pcg_gmg"} and len(mem) == 4
    assert (mem["mem_peak_mb"] > 0).all()
    for level in (0, 1):
        assert mem.loc[("tnnmg", level), "mem_input_mb"] == \
            mem.loc[("amg_pcg_gmg", level), "mem_input_mb"] > 0
    newton = s[s.config == "semismooth_newton"]
    assert (newton["status"] == "converged").all() and (newton["energy_error"] <= 1e-6).all()
    assert (newton["t_to_target"] == newton["t_setup"] + newton["t_solve"]).all()
    assert set(s.loc[s.config == "reference", "reference"]) == {"pdas"}
    runs = s[s.config == "alg84"]
    assert list(runs["NC"]) == [17, 33] and runs["stop_8_25"].all()
    assert (runs["energy_error"] < 1e-2).all() and (runs["kappa_SinvS"] < 10).all()
    outs = [str(tmp_path / n) for n in ("table.csv", "claims.csv", "time.png", "kappa.png",
                                        "tnnmg.png")]
    run("report.augmented_projection", "--study", str(study), "--thesis",
        str(ROOT / "reference" / "table_9_1.csv"), "--table", outs[0], "--claims", outs[1],
        "--fig-time", outs[2], "--fig-kappa", outs[3], "--fig-tnnmg", outs[4])
    assert Path(outs[4]).stat().st_size > 0
    table = pd.read_csv(outs[0]).set_index("level")
    assert table.loc[1, "thesis_nodes"] == 4226 and pd.isna(table.loc[0, "thesis_nodes"])
    assert table.loc[1, "thesis_n_outer_1e-03"] == 19 and table.loc[1, "n_outer_1e-03"] > 0
    claims = pd.read_csv(outs[1])
    assert {"claim", "measured", "bar", "pass"} <= set(claims.columns) and len(claims) >= 2
    ratios = claims[claims.claim.str.startswith("Alg. 8.4's time to the energy-error target")]
    # no published bar: Alg. 8.4's and its best variant's ratios to a linear solve are reported, not judged
    assert len(ratios) == 2 and set(ratios.bar) == {"-"} and ratios["pass"].isna().all()
    assert (ratios.measured.astype(float) > 0).all()
    ours = claims[claims.claim.str.startswith("tnnmg")]
    assert len(ours) == 5 and set(ours.bar.astype(float)) == {0.15, 2.0, 1.5}
    memory = ours[ours.claim.str.contains("peak memory")]
    want = (mem.loc[("tnnmg", 1), ["mem_input_mb", "mem_peak_mb"]].sum()
            / mem.loc[("amg_pcg_gmg", 1), ["mem_input_mb", "mem_peak_mb"]].sum())
    assert float(memory.measured.iloc[0]) == pytest.approx(want)


def test_median_run_keeps_the_median_runs_row_and_the_spread():
    from workflows.measure import median_run
    times = iter([3.0, 1.0, 2.0, 5.0, 4.0])
    row = median_run(lambda: (t := next(times), {"t_to_target": t, "tag": t})[1], 5)
    assert row == {"t_to_target": 3.0, "tag": 3.0, "t_to_target_min": 1.0,
                   "t_to_target_max": 5.0, "timing_repeats": 5}
    calls = []
    row = median_run(lambda: calls.append(1) or {"t_to_target": np.nan}, 3)
    assert len(calls) == 1 and row["timing_repeats"] == 1       # not reached: not repeated
    with pytest.raises(ValueError, match="repeats must be >= 1"):
        median_run(dict, 0)


def test_interleaved_runs_take_turns_and_keep_each_median():
    """Timings compared as a ratio are taken in rounds (a, b, a, b, ...), each run's median
    kept as median_run keeps it; a run that does not reach its target is not repeated."""
    from workflows.measure import interleaved_median_runs
    order = []
    times = {"a": iter([3.0, 1.0, 2.0]), "b": iter([9.0, 7.0, 8.0])}

    def run(name):
        return lambda: order.append(name) or {"t_to_target": next(times[name])}

    rows = interleaved_median_runs({"a": run("a"), "b": run("b"),
                                    "never": lambda: order.append("n") or {}}, 3)
    assert order == ["a", "b", "n", "a", "b", "a", "b"]
    assert rows["a"]["t_to_target"] == 2.0 and rows["b"]["t_to_target"] == 8.0
    assert rows["b"]["t_to_target_min"] == 7.0 and rows["b"]["timing_repeats"] == 3
    assert rows["never"]["timing_repeats"] == 1


def test_augmented_projection_study_beyond_a_factorisation(tmp_path):
    """The route for sizes no Cholesky reaches: TNNMG to 1e-10, verified, as the reference,
    and no Alg. 8.4 configuration; its energy error agrees with the exact reference's."""
    study = tmp_path / "study.csv"
    run("workflows.studies.augmented_projection.run", *SCENE, "--levels", "1", "--configs",
        "--no-newton", "--reference", "tnnmg", "--ref-cache", str(tmp_path), "--out",
        str(study))
    s = pd.read_csv(study).set_index("config")
    assert set(s.index) == {"reference", "tnnmg", "tnnmg_nested", "amg_pcg_gmg", "amg_pcg_sa"}
    assert s.loc["reference", "reference"] == "tnnmg"
    assert s.loc["reference", "status"] == "converged"
    assert s.loc["reference", "kkt_max"] <= 1e-10
    assert (s.loc[["tnnmg", "tnnmg_nested"], "energy_error"] <= 1e-6).all()
    from problems.kkt import energy_error
    from problems.spec import problems
    from solvers.reference import reference_solve
    qp = problems()["circle_square"].make(1)
    cached = np.load(tmp_path / "circle_square_L1.npz")
    assert energy_error(qp, cached["u"], reference_solve(qp, tol=1e-10).u) <= 1e-8


def test_laplace_scripts_and_reports(tmp_path):
    runs = []
    for case in ("sin10x", "linear"):
        for side in ("coarse", "fine"):
            runs.append(str(tmp_path / f"{case}_{side}.csv"))
            run("workflows.studies.laplace_nonmatching.run", "--case", case, "--constrained", side,
                "--levels", "0", "1", "2", "--out", runs[-1])
    outs = {k: str(tmp_path / f"{k}.csv") for k in ("errors", "by-side", "rates")}
    run("report.laplace_nonmatching", "tables", "--inputs", *runs, "--default-side", "coarse",
        *[a for k, v in outs.items() for a in (f"--{k}", v)])
    rates = pd.read_csv(outs["rates"])
    row = rates[(rates.case == "linear") & (rates.variant == "nodal")
                & (rates.constrained == "coarse")]
    assert abs(row["rate_h1"].iloc[0] - 0.5) < 0.1      # Theorem 6.17's O(h^1/2), patch test
    run("report.laplace_nonmatching", "convergence", "--errors", outs["by-side"], "--rates", outs["rates"],
        "--case", "sin10x", "--out", str(tmp_path / "conv.png"))
    run("report.laplace_nonmatching", "mesh", "--level", "0", "--ratio", "2:3", "--out", str(tmp_path / "m.png"))
    assert (tmp_path / "conv.png").stat().st_size > 0 and (tmp_path / "m.png").stat().st_size > 0


def test_assembly_benchmark_script(tmp_path, capsys):
    out = tmp_path / "assembly.csv"
    assert run("workflows.scripts.bench_assembly", "--n", "6", "--repeat", "1", "--out",
               str(out)) is None
    t = pd.read_csv(out)
    assert set(t["case"]) == {"ours", "skfem", "ngsolve", "amg"}
    assert t["check"].fillna("").str.contains("max|K-K").any()


def test_scripts_reject_bad_arguments(capsys):
    with pytest.raises(SystemExit) as err:
        run("workflows.studies.contact_solution.run", "--problem", "circle_square", "--set", "E1=-1",
            "--level", "0", "--outdir", "/nonexistent")
    assert err.value.code == 2 and "'E1'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as err:
        run("workflows.studies.solver_comparison.run", "--problem", "laplace_nonmatching",
            "--level", "0", "--out", "x.csv")
    assert err.value.code == 2 and "not a contact problem" in capsys.readouterr().err


# --------------------------------------------------------------------------- Snakemake
def snakemake(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([str(SNAKEMAKE), *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_snakemake_dry_run_plans_every_study():
    out = snakemake("-n", "--forceall", "--quiet", "rules")
    assert out.returncode == 0, out.stderr[-2000:]
    for rule in ("contact_level", "solver_comparison", "augmented_projection_study",
                 "laplace_errors", "adaptive_study", "adaptive_figures", "patch_test",
                 "roll_stack_study", "roll_stack_report", "all"):
        assert rule in out.stdout


def test_snakemake_lint_is_clean():
    out = snakemake("--lint")
    text = out.stdout + out.stderr
    assert out.returncode == 0 and "Lints for" not in text, text[-3000:]
    assert "Congratulations, your workflow is in a good condition" in text


def test_a_new_scene_joins_a_study_by_config_alone(tmp_path):
    """Adding a scene is a config change only: its jobs land under results/<scene>/."""
    config = load_config(ROOT / "workflows/config/quick.yaml")
    config["scenes"]["circle_square_stiff"] = {"problem": "circle_square", "params": {"E2": 10.0}}
    config["solver_comparison"]["scenes"]["circle_square_stiff"] = [1]
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config))
    out = snakemake("-n", "-p", "--forceall", "--configfile", str(path))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "results/circle_square_stiff/solvers_L1.csv" in out.stdout
    assert "results/circle_square_stiff/solvers.csv" in all_targets(config)
    assert "--problem circle_square --set E2=10.0 --level 1" in out.stdout


@pytest.mark.parametrize("change, needle", [
    (lambda c: c["scenes"].update(bad={"problem": "nope"}), "'scenes.bad.problem': 'nope'"),
    (lambda c: c["scenes"].update(bad={"problem": "circle_square", "params": {"E1": -1}}),
     "'scenes.bad.params'"),
    (lambda c: c["solver_comparison"]["scenes"].update(ghost=[1]),
     "'solver_comparison.scenes.ghost': no such scene"),
    (lambda c: c["contact_solution"]["scenes"].update(circle_square=[7]), "levels [7]"),
    (lambda c: c["augmented_projection"].update(configs=["alg85"]), "'alg85' is not allowed"),
    (lambda c: c["adaptive"].update(variants=["eta3"]), "'adaptive.variants': 'eta3'"),
    (lambda c: c["adaptive"]["scenes"].update(circle_square=[0, 1]), "one start level"),
    (lambda c: c["adaptive"]["max_nodes"].pop("cube_sphere"), "no node budget"),
    (lambda c: (c["scenes"].update(rolls={"problem": "roll_stack"}),
                c["adaptive"]["patch_test"]["scenes"].update(rolls=[0])),
     "problem 'roll_stack' does not offer the couplings"),
    (lambda c: c["hard_cases"]["incompressibility"].update(scenes=["laplace_nonmatching"]),
     "'hard_cases.incompressibility.scenes': 'laplace_nonmatching' is not allowed"),
    (lambda c: c["hard_cases"]["scenes"].update(hard_stiff_circle=[1]),
     "'hard_cases.scenes.hard_stiff_circle': levels [1] are not among the test set's runs"),
    (lambda c: c["test_set"].update(exclude_families=["roll_stak"]),
     "'test_set.exclude_families': 'roll_stak' is not a family"),
    (lambda c: c.update(shared=["contact_level"]),
     "'shared': 'contact_level' is not a timing rule"),
    (lambda c: c["hard_cases"]["incompressibility"].update(level=9),
     "'hard_cases.incompressibility' for 'circle_square'"),
    (lambda c: c["hard_cases"]["random_friction"].update(solvers=["tnnmg", "tnmg"]),
     "'hard_cases.random_friction.solvers': ['tnmg'] are not allowed"),
    (lambda c: c["element_order"]["reference_level"].update(circle_square=2),
     "'element_order.reference_level.circle_square': 2 is not allowed; allowed: a level in 3.."),
    (lambda c: c["element_order"]["reference_level"].update(ghost=2),
     "'element_order.reference_level.ghost': not among element_order.scenes"),
    (lambda c: (c["scenes"].update(cs_p2={"problem": "circle_square",
                                          "params": {"degree": 2}}),
                c["element_order"]["scenes"].update(cs_p2=[0])),
     "'element_order.scenes.cs_p2': the scene sets 'degree'"),
])
def test_config_errors_name_the_key(change, needle):
    config = load_config(ROOT / "workflows/config/quick.yaml")
    change(config)
    with pytest.raises(ConfigError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        check_config(config)


def test_config_schema_rejects_unknown_keys(tmp_path):
    config = load_config(ROOT / "workflows/config/quick.yaml")
    config["solver_comparison"]["timelimit"] = 5
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config))
    out = snakemake("-n", "--configfile", str(path))
    assert out.returncode != 0 and "timelimit" in out.stdout + out.stderr


def test_studies_declare_their_outputs_once():
    config = load_config(ROOT / "workflows/config/quick.yaml")
    targets = all_targets(config)
    assert len(targets) == len(set(targets))
    assert "results/circle_square/augmented_projection_table.csv" in targets
    assert {s for s in STUDIES} >= {"laplace_nonmatching", "contact_solution",
                                     "solver_comparison", "augmented_projection", "hard_cases",
                                     "adaptive"}
    assert "results/hard_cases/hard_cases.csv" in targets           # one table across scenes
    assert "results/circle_square/adaptive_table.csv" in targets
    assert "results/flat_blocks/patch_test.png" in targets          # the patch test's extra
    assert not any(t.startswith("results/flat_blocks/adaptive") for t in targets)
    smk = "".join(p.read_text() for p in (ROOT / "workflows").rglob("*.smk"))
    assert "results/" not in smk          # every path comes from workflows/studies/


@pytest.mark.parametrize("scale", ["quick", "huge"])
def test_slurm_profile_dry_run_plans_every_job_with_its_resources(scale):
    """Under workflows/profiles/slurm (the executor plugin is in the test extra) a dry run
    plans every job; each heavy rule's jobs carry the mem_mb and runtime its config
    declares, every other job the profile's defaults. ``huge`` is the scale meant for
    a cluster (the cluster's planning command)."""
    from workflows.studies import HEAVY_RULES

    config = load_config(ROOT / f"workflows/config/{scale}.yaml")
    out = snakemake("-n", "--forceall", "--profile", "workflows/profiles/slurm",
                    "--configfile", f"workflows/config/{scale}.yaml")
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
    jobs = re.findall(r"^rule (\w+):\n(.*?)(?=^\[|\Z)", out.stdout, flags=re.M | re.S)
    counts = dict(re.findall(r"^(\w+)\s+(\d+)$", out.stdout, flags=re.M))
    assert len(jobs) == int(counts["total"]) and len(jobs) >= 50
    for rule, block in jobs:
        res = dict(re.findall(r"(\w+)=([^,\s]+)", re.search(r"resources: (.*)", block)[1]))
        want = config["resources"][rule] if rule in HEAVY_RULES else {"mem_mb": 1000,
                                                                     "runtime": 10}
        assert int(res["mem_mb"]) == want["mem_mb"] and int(res["runtime"]) == want["runtime"], (
            rule, res)
    assert set(HEAVY_RULES) <= {rule for rule, _ in jobs}
    # the distributed solves: one MPI job per scene with the most ranks as Slurm tasks of
    # one CPU each and the configured launcher as 'mpi'
    ps = config["petsc_scaling"]
    mpi = [dict(re.findall(r"(\w+)=([^,\s]+)", re.search(r"resources: (.*)", block)[1]))
           for rule, block in jobs if rule == "petsc_scaling_study"]
    assert len(mpi) == len(ps["scenes"])
    for res in mpi:
        assert (int(res["tasks"]), int(res["cpus_per_task"]), res["mpi"]) == (
            max(ps["ranks"]), 1, ps["launcher"])


def test_every_heavy_rule_has_a_benchmark_and_measured_resources():
    from workflows.studies import HEAVY_RULES

    smk = {str(p): p.read_text() for p in (ROOT / "workflows").rglob("*.smk")}
    for rule in HEAVY_RULES:
        text = next(t for t in smk.values() if f"rule {rule}:" in t)
        block = text.split(f"rule {rule}:")[1].split("\nrule ")[0]
        assert f'bench_path("{rule}"' in block and f'rule_resources(config, "{rule}")' in block
    for scale in ("tiny", "quick", "full", "huge"):
        config = load_config(ROOT / f"workflows/config/{scale}.yaml")
        check_config(config)                         # a configured study needs its resources
        config["resources"].pop("contact_level")
        with pytest.raises(ConfigError, match="'resources.contact_level'"):
            check_config(config)
    config["resources"]["contact_levels"] = {"mem_mb": 100, "runtime": 1}
    with pytest.raises(ConfigError, match="'resources.contact_levels': not a heavy rule"):
        check_config(config)


def test_timing_rules_take_the_whole_machine_share():
    """"Run alone" is a named resource, not ``threads: 2``: the local profile provides
    the share, every job takes 1 by default and a timing rule all of it, unless the
    scale lets it share the machine (``shared``: the quick scale's test-set runs)."""
    from workflows.studies import MACHINE_SHARE, RUNS_ALONE

    name, whole = MACHINE_SHARE
    profile = yaml.safe_load((ROOT / "workflows/profiles/default/config.yaml").read_text())
    assert profile["resources"][name] == whole and profile["default-resources"][name] == 1
    out = snakemake("-n", "--forceall", "--profile", "workflows/profiles/default")
    assert out.returncode == 0, (out.stdout + out.stderr)[-3000:]
    jobs = re.findall(r"^rule (\w+):\n(.*?)(?=^\[|\Z)", out.stdout, flags=re.M | re.S)
    shares = {rule: int(re.search(rf"{name}=(\d+)", block)[1]) for rule, block in jobs}
    assert RUNS_ALONE <= set(shares)
    shared = set(load_config(ROOT / "workflows/config/quick.yaml")["shared"])
    assert shared and shared < RUNS_ALONE
    alone = RUNS_ALONE - shared
    assert all((share == whole) == (rule in alone) for rule, share in shares.items()), shares
    assert not any("threads:" in p.read_text() for p in (ROOT / "workflows").rglob("*.smk"))


def test_freed_memory_is_returned_between_phases():
    """What only a reference cycle holds (200 MB here) stays resident until Python's
    next full collection; return_freed_memory collects it and the resident memory
    falls by its size."""
    import gc

    import psutil

    from workflows.measure import return_freed_memory

    class Node:
        pass

    was_enabled = gc.isenabled()
    gc.disable()                                # no automatic collection in between
    try:
        a, b = Node(), Node()
        a.other, b.other = b, a                 # a cycle
        a.data = np.ones(25_000_000)            # 200 MB, touched
        del a, b
        held = psutil.Process().memory_info().rss
        return_freed_memory()
        freed = held - psutil.Process().memory_info().rss
    finally:
        if was_enabled:
            gc.enable()
    assert freed >= 150e6
