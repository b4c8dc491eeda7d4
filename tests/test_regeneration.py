"""The whole regeneration, end to end, at the tiny scale (workflows/config/tiny.yaml):
every target made, the HTML report opened in headless Chromium with every figure present,
an interrupted run resumed without redoing finished jobs or leaving a half-written file,
and every table a solving job writes made twice, identical apart from timing columns.

Two regenerations run here: a plain one of every target, and one of every solving job
(the rules that solve, :data:`SOLVING`: each study's heavy rules, whose tables the reports
read) that is interrupted (SIGINT to the whole process group, as Ctrl-C does) and then
resumed. Every table a solving job writes is thus made twice, by separate processes, and
the two must agree; the report jobs (tables and figures drawn from those tables) run once.
"""
from __future__ import annotations

import base64
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from compare_results import differences, tables
from workflows.io import META, PARTIAL, check_result
from workflows.studies import PATHS, STUDIES, all_targets, load_config
from workflows.table_pages import page_path

ROOT = Path(__file__).resolve().parent.parent
SNAKEMAKE = Path(sys.executable).parent / "snakemake"
TINY = ROOT / "workflows/config/tiny.yaml"
PROFILE = ROOT / "workflows/profiles/default"

def regenerate(cwd: Path, *extra: str, popen: bool = False, env: dict | None = None):
    # greedy job selection: the profile's (ilp) runs a MILP in a CBC subprocess at every
    # scheduling round, CPU time the other tests beside this run need (docs/performance.md)
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "--configfile", str(TINY),
           "--profile", str(PROFILE), "--cores", "2", "--scheduler", "greedy", *extra]
    if popen:     # SIGINT handled as a terminal's Ctrl-C is, even under a shell that started
                  # this test in the background (its jobs inherit SIGINT ignored)
        return subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, start_new_session=True, env=env,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=1800, env=env)


#: The job the interrupted run holds: ``report.laplace_nonmatching tables`` (rule laplace_summary),
#: which starts only after its four ``laplace_errors`` jobs have finished and has jobs
#: after it. A ``sitecustomize`` on the jobs' PYTHONPATH (test-only, nothing in the
#: workflow knows of it) marks the job as started and keeps it running until the test's
#: SIGINT ends it: the interrupt lands inside a job whatever the machine's speed.
HELD_JOB = ("report.laplace_nonmatching", "tables")
HELD_RULE = "laplace_summary"
GATE = f"""
import os, sys, time
from pathlib import Path
_gate = os.environ.get("CONTACTBENCH_TEST_GATE")
if _gate and set({HELD_JOB!r}) <= set(getattr(sys, "orig_argv", ())):
    Path(_gate, "held").write_text(str(os.getpid()))
    while True:                       # until the test's SIGINT
        time.sleep(0.1)
"""


#: The rules whose outputs the resumed run makes: every study's heavy rules (those that
#: solve, with a benchmark file), and the held job's rule.
SOLVING = frozenset({rule for study in STUDIES.values() for rule in study.heavy_rules}
                     | {HELD_RULE})


def targets() -> list[str]:
    """Every file the tiny run makes: the scale file read as the workflow reads it, with
    the sections its studies declare at the tiny scale (``scale: tiny``)."""
    config = load_config(TINY)
    return all_targets(config) + [PATHS["summary_html"], PATHS["summary_claims"],
                                  PATHS["summary_landing"]]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    cwd = tmp_path_factory.mktemp("tiny")
    out = regenerate(cwd)
    assert out.returncode == 0, (out.stdout + out.stderr)[-4000:]
    (cwd / "snakemake.log").write_text(out.stdout + out.stderr)
    return cwd


@pytest.fixture(scope="module")
def resumed_run(tmp_path_factory, tiny_run):
    """A regeneration of the :data:`SOLVING` rules' outputs (the plain run's, as targets)
    interrupted (SIGINT to its process group, as Ctrl-C) while the held job
    (:data:`HELD_JOB`) runs, then resumed with the same command; with the outputs it was
    asked for."""
    wanted = solving_outputs(tiny_run)
    cwd = tmp_path_factory.mktemp("resumed")
    gate = tmp_path_factory.mktemp("gate")
    (gate / "sitecustomize.py").write_text(GATE)
    env = {**os.environ, "CONTACTBENCH_TEST_GATE": str(gate),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(gate), os.environ.get("PYTHONPATH")]))}
    proc = regenerate(cwd, *wanted, popen=True, env=env)
    held = gate / "held"
    while not held.exists() and proc.poll() is None:
        time.sleep(0.2)
    if proc.poll() is not None:
        pytest.fail("the run ended before the held job started:\n" + proc.communicate()[0][-4000:])
    os.killpg(proc.pid, signal.SIGINT)
    log = proc.communicate(timeout=300)[0]
    assert proc.returncode != 0, "the interrupted run claims success"
    written = [p for p in (cwd / "results").rglob("*")
               if p.is_file() and Path(str(p) + META).exists()]
    broken = [str(p) for p in written if not check_result(p)]
    after_interrupt = {cwd / f: (cwd / f).stat().st_mtime_ns for f in finished_outputs(log)}
    resumed = regenerate(cwd, *wanted)
    return cwd, log, after_interrupt, broken, resumed, wanted


def jobs(log: str) -> dict[int, tuple[str, list[str]]]:
    """``{jobid: (rule, outputs)}`` of the jobs Snakemake's ``log`` reports started."""
    return {jobid: (rule, outputs) for kind, jobid, rule, outputs in job_events(log)
            if kind == "start"}


def finished_outputs(log: str) -> set[str]:
    """The outputs of the jobs Snakemake's ``log`` reports finished.

    A job interrupted after writing some of its outputs is not finished: Snakemake marks
    its outputs incomplete and rightly reruns it, so the test judges by jobs, not files.
    """
    started = jobs(log)
    done = {int(m) for m in re.findall(r"^Finished jobid: (\d+)", log, flags=re.M)}
    return {f for jobid in done & started.keys() for f in started[jobid][1]}


def solving_outputs(run: Path) -> list[str]:
    """The outputs of the :data:`SOLVING` rules' jobs in the plain ``run`` (its log)."""
    log = (run / "snakemake.log").read_text()
    return sorted(f for rule, outputs in jobs(log).values() if rule in SOLVING
                  for f in outputs)


def test_tiny_regeneration_makes_every_target(tiny_run):
    missing = [t for t in targets() if not (tiny_run / t).exists()]
    assert not missing
    claims = pd.read_csv(tiny_run / PATHS["summary_claims"], keep_default_na=False)
    assert len(claims) >= 10 and set(claims["result"]) <= {"pass", "miss", "n/a"}
    assert (claims["thesis"].str.len() > 1).all()     # every claim names its source
    out = regenerate(tiny_run, "-n")
    assert out.returncode == 0 and "Nothing to be done" in out.stdout + out.stderr


def test_no_result_reports_a_bound_below_its_floor(tiny_run):
    """Every result table that reports a certified energy bound has its floor beside it,
    and no row's bound lies below that floor (a gap known only to rounding certifies
    nothing smaller)."""
    tables = 0
    for path in sorted((tiny_run / "results").rglob("*.csv")):
        t = pd.read_csv(path)
        if "energy_bound" not in t:
            continue
        tables += 1
        assert "energy_bound_floor" in t, path
        both = t[["energy_bound", "energy_bound_floor"]].dropna()
        assert (both["energy_bound"] >= both["energy_bound_floor"]).all(), path
    assert tables >= 3


def test_the_leaderboards_read_without_running_anything(tiny_run):
    """A Markdown results page per problem class with its settings beside it, and the
    solver named fastest verified the one a reader computes from the runs table: the
    best median time ratio among the solvers verified on at least 90 % of the class."""
    import numpy as np

    from workflows.problem_set import PROBLEM_CLASSES
    folder = tiny_run / "results/solver_summary"
    for cls in PROBLEM_CLASSES:
        text = (folder / f"leaderboard_{cls}.md").read_text()
        assert text.startswith(f"# Leaderboard: {PROBLEM_CLASSES[cls]}")
        for words in ("**Shift**", "**Time limit** 20 s", "**Repeats**: the counted rung is "
                      "run 3 times", "**Load**", "**Machine**", "**Versions**"):
            assert words in text, (cls, words)
    runs = pd.concat([pd.read_csv(p) for p in
                      (tiny_run / "results/test_set").rglob("runs/*/*.csv")])
    cold = runs[(runs.start == "cold") & (runs.problem_class == "frictionless")
                & (runs.preset == "mid")]
    counted = cold[cold.counted.astype(bool)].set_index(["problem", "solver"])["time_median"]
    problems = sorted(cold.problem.unique())
    contest = [s for s in cold.solver.unique() if s != "pdas"]
    best = {p: min(counted[p, s] for s in contest if (p, s) in counted) for p in problems}
    ratio = {s: np.median([counted[p, s] / best[p] if (p, s) in counted else np.inf
                           for p in problems]) for s in contest}
    covering = [s for s in contest
                if sum((p, s) in counted for p in problems) >= 0.9 * len(problems)]
    boards = pd.read_csv(folder / "leaderboards.csv")
    board = boards[(boards.problem_class == "frictionless") & (boards.preset == "mid")]
    assert board[board.fastest.astype(bool)].solver.tolist() == [min(covering, key=ratio.get)]
    assert board[board.standing == "reference"].solver.tolist() == ["pdas"]
    # each ladder that goes on draws a line: at least three rungs
    taken = cold.groupby(["problem", "solver"]).filter(
        lambda g: g.loc[g.rung == 0, "status"].isin(["converged", "inaccurate"]).all())
    assert (taken.groupby(["problem", "solver"]).rung.nunique() >= 3).all()


def job_events(log: str) -> list[tuple[str, int, str, list[str]]]:
    """``("start" | "finish", jobid, rule, outputs)`` in the order Snakemake's ``log``
    reports them (a finish names neither rule nor outputs)."""
    events, rule, outputs = [], None, []
    for line in log.splitlines():
        if m := re.match(r"^(?:local)?rule (\w+):$", line):
            rule, outputs = m[1], []
        elif line.strip().startswith("output:"):
            outputs = [f.strip() for f in line.strip()[len("output:"):].split(",")]
        elif (m := re.match(r"^\s+jobid: (\d+)$", line)) and rule is not None:
            events.append(("start", int(m[1]), rule, outputs))
            rule = None
        elif m := re.match(r"^Finished jobid: (\d+)", line):
            events.append(("finish", int(m[1]), "", []))
    return events


def test_timing_jobs_run_alone(tiny_run):
    """The profile's named resource (``machine_share``, workflows.studies.RUNS_ALONE) at work on two
    cores: no job starts while a timing job runs, and a timing job starts only when
    nothing else runs."""
    from workflows.studies import RUNS_ALONE

    events = job_events((tiny_run / "snakemake.log").read_text())
    started = {jobid: rule for kind, jobid, rule, _ in events if kind == "start"}
    timed = RUNS_ALONE & set(started.values())        # the tiny scale runs most of them
    assert len(timed) >= 5, timed
    assert len(started) > 20 and {j for k, j, _, _ in events if k == "finish"} == set(started)
    running, overlapped = set(), 0
    for kind, jobid, rule, _ in events:
        if kind == "finish":
            running.discard(jobid)
            continue
        alone = [started[j] for j in running | {jobid} if started[j] in RUNS_ALONE]
        assert not (alone and running), (rule, [started[j] for j in running])
        overlapped += bool(running)
        running.add(jobid)
    assert overlapped > 0      # the other jobs did run two at a time: the check can fail


def test_every_result_has_provenance(tiny_run):
    import json

    for t in targets():
        meta = json.loads(Path(str(tiny_run / t) + META).read_text())
        prov = meta["provenance"]
        assert prov["commit"] and prov["cpu_model"] and prov["packages"]["numpy"]
        assert prov["configfile"].endswith("tiny.yaml") and len(prov["config_sha256"]) == 64


#: Headless Chromium as root on a closed network (no sandbox, no background traffic).
BROWSER_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run"]


def chromium() -> str | None:
    path = os.environ.get("CONTACTBENCH_CHROMIUM") or shutil.which("chromium") or shutil.which(
        "chromium-browser")
    return path if path and Path(path).exists() else None


def test_html_report_opens_in_chromium_with_every_figure(tiny_run):
    """Snakemake's report in a real (headless) browser: the summary page's category comes
    first, and every registered figure renders as a decoded image."""
    if chromium() is None:
        if os.environ.get("CONTACTBENCH_CHROMIUM"):
            pytest.fail(f"CONTACTBENCH_CHROMIUM={os.environ['CONTACTBENCH_CHROMIUM']} not found")
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    out = regenerate(tiny_run, "--report", "report.html")
    assert out.returncode == 0, out.stderr[-3000:]
    figures = sorted(t for t in targets() if t.endswith(".png"))
    assert len(figures) >= 15
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page()
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto((tiny_run / "report.html").as_uri())
        page.wait_for_selector("text=0 summary", timeout=60_000)
        shown = report_figures(page)
        kinds = page.evaluate("Object.values(results).map(r => r.mime_type)")
        registered = page.evaluate("Object.keys(results)")
        browser.close()
    assert not errors
    # a table is shown as a page, never offered as a CSV to download
    assert "text/csv" not in kinds and not [k for k in registered if k.endswith(".csv")]
    pages = [page_path(t) for t in targets()
             if t.endswith(".csv") and (tiny_run / page_path(t)).exists()]
    assert len(pages) >= 10 and set(pages) <= set(registered), set(pages) - set(registered)
    assert sorted(shown) == figures, set(figures) ^ set(shown)
    assert all(size[0] > 100 and size[1] > 100 for size in shown.values()), shown


def report_html(run: Path) -> Path:
    """The run's Snakemake report (``report.html``), made if not yet there."""
    report = run / "report.html"
    if not report.exists():
        out = regenerate(run, "--report", "report.html")
        assert out.returncode == 0, out.stderr[-3000:]
    return report


def open_result(page, path: str) -> None:
    """Open the report's result ``path`` as a reader would: home, the report's search,
    the result's eye button."""
    page.locator("nav ol li a").first.click()                 # home
    search = page.locator("input[placeholder='Search...']")
    search.fill(path)
    search.press("Enter")
    page.locator(f"tr:has-text('{path}')").first.locator("a[iconname=eye]").click()


def report_figures(page) -> dict[str, tuple[int, int]]:
    """Every PNG the report registers, found through the report's own search and opened
    with its eye button as a reader would; returns file name -> the decoded image's
    natural size (``img.decode()`` fails on a broken image)."""
    registered = page.evaluate("Object.keys(results)")
    shown = {}
    for path in (k for k in registered if k.endswith(".png")):
        open_result(page, path)
        name = Path(path).name
        img = page.wait_for_selector(f"img[src*='filename={name};']", timeout=20_000)
        shown[path] = tuple(page.evaluate(
            "i => i.decode().then(() => [i.naturalWidth, i.naturalHeight])", img))
    return shown


def test_summary_page_renders_in_the_report(tiny_run):
    """The summary page (category '0 summary', first in the menu) shows its provenance
    and the counts of checked claims."""
    if chromium() is None:
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    report = report_html(tiny_run)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page()
        page.goto(report.as_uri())
        page.wait_for_selector("text=0 summary", timeout=60_000)
        menu = page.locator("nav li a").all_inner_texts()
        page.click("text=0 summary")
        page.click("nav >> text=summary >> nth=-1")
        page.locator("tr:has-text('summary.html')").first.locator("a[iconname=eye]").click()
        summary = page.frame_locator("iframe").first          # the report shows HTML framed
        summary.locator("text=Checked claims").wait_for(timeout=20_000)
        body = summary.locator("body").inner_text()
        browser.close()
    results = [m.strip() for m in menu if m.strip()]
    assert results.index("0 summary") < results.index("circle_square")
    assert "Provenance" in body and re.search(r"\d+ pass", body) and "Table 9.1" in body


def test_the_report_opens_on_the_headline(tiny_run):
    """The HTML report's landing page is the run's headline: the title says what the suite
    covers, the claims' counts are the summary's, the leaderboards' verdicts follow, and in
    headless Chromium at 1400 x 900 px all of it is on the first screen."""
    from collections import Counter

    from report.summary import TITLE

    landing = (tiny_run / PATHS["summary_landing"]).read_text(encoding="utf-8")
    counts = Counter(pd.read_csv(tiny_run / PATHS["summary_claims"],
                                 keep_default_na=False)["result"])
    claims_line = (f"**Claims checked**: {counts['pass']} pass, {counts['miss']} miss, "
                   f"{counts['n/a']} not judged at this scale")
    assert landing.splitlines()[0] == TITLE and "frictional" in TITLE
    assert claims_line in landing and "Solver leaderboards" in landing
    lines = landing.splitlines()
    board = lines[lines.index(next(l for l in lines if l.startswith("Solver leaderboards"))) + 2]
    assert board.startswith("- **")
    board = board[4:].split("**")[0]        # the first board's problem class
    if chromium() is None:
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    report = report_html(tiny_run)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(report.as_uri())
        page.wait_for_selector("text=0 summary", timeout=60_000)
        boxes = {text: page.get_by_text(text).first.bounding_box()
                 for text in (TITLE, "Claims checked", "Solver leaderboards", board)}
        browser.close()
    for text, box in boxes.items():       # on the first screen, the title not cut off above
        assert box is not None and 0 <= box["y"] <= box["y"] + box["height"] <= 900, (text, box)


#: What the figure audit refuses in a study's log: matplotlib's warnings (an empty legend,
#: a layout that could not fit, a font without a glyph).
PLOT_WARNING = re.compile(r"UserWarning|No artists with labels|MatplotlibDeprecationWarning|"
                          r"tight_layout not applied|Glyph \d+")


def test_every_figure_is_drawn_and_titled_with_its_own_scene(tiny_run):
    """The figure audit (report/figure_audit.py) on every figure the report registers: it
    decodes, has drawn data in every panel (or says why it has nothing to draw), names its
    own scene and no other in its title, every legend entry is drawn and no legend lies over
    the data, no text reads nan, every panel has its axis labels (a time or memory with its
    unit, colours with a labelled colourbar or key), its text is legible in the report's
    ~950 px frame, each solver has one colour and marker across all figures, and no study
    logged a matplotlib warning."""
    import json

    from report.figure_audit import png_problems, png_text, style_conflicts
    from report.figures import AUDIT_KEYS
    figures = sorted(t for t in targets() if t.endswith(".png"))
    assert len(figures) >= 15
    audits = {f: png_text(tiny_run / f)[0] for f in figures}
    scenes = {a["contactbench:scene"] for a in audits.values()} - {""}
    assert {"circle_square", "cube_sphere", "roll_stack"} <= scenes
    problems, styles = {}, {}
    for f, audit in audits.items():
        assert set(AUDIT_KEYS) <= set(audit), f
        styles[f] = json.loads(audit["contactbench:solver_styles"])
        problems[f] = png_problems(tiny_run / f, scenes)
        if audit["contactbench:nothing_to_draw"]:
            assert int(audit["contactbench:data_artists"]) == 0, f
            continue
        assert int(audit["contactbench:data_artists"]) > 0, f
        assert audit["contactbench:empty_panels"] == "0", f
    assert not {f: p for f, p in problems.items() if p}
    assert sum(bool(s) for s in styles.values()) >= 3      # solvers' styles were compared
    assert style_conflicts(styles) == []
    warned = [f"{log}: {line.strip()}" for log in (tiny_run / "results" / "logs").rglob("*")
              if log.is_file() for line in log.read_text(errors="replace").splitlines()
              if PLOT_WARNING.search(line)]
    assert not warned, warned[:5]


def charts_of_run() -> list[str]:
    """The interactive chart pages the run registers: one beside each charted figure
    (report/charts.py: CHARTED)."""
    from report.charts import chart_path, charted
    return sorted({chart_path(t) for t in targets() if t.endswith(".png") and charted(t)})


def test_every_chart_is_valid_vega_lite_with_the_figures_colours(tiny_run):
    """Each registered chart page: Vega-Lite v5 specs (Snakemake's bundled version) with
    inline, non-empty data and encodings naming fields of the data, every solver in the
    PNGs' colour, and the scripts inline (nothing fetched from the network)."""
    from report.charts import SCRIPTS, page_scripts, page_specs, spec_problems
    from matplotlib.colors import to_hex

    from report.figures import solver_style
    pages = charts_of_run()
    assert len(pages) >= 2, pages       # the test set's, and circle_square's solver times
    for rel in pages:
        text = (tiny_run / rel).read_text()
        assert not re.search(r"<script[^>]+src=|<link[^>]+href=\s*['\"]?http", text), rel
        assert set(page_scripts(text)) == set(SCRIPTS) and "vegaEmbed" in text
        assert len(base64.b64encode(text.encode())) < 2_000_000     # the report frames it
        specs = page_specs(text)
        assert specs, rel
        for spec in specs:
            assert spec_problems(spec) == [], (rel, spec.get("title"), spec_problems(spec))
            layers = spec.get("spec", spec)["layer"]
            scale = layers[0]["encoding"]["color"]["scale"]
            assert scale["range"] == [to_hex(solver_style(s)["color"]) for s in scale["domain"]]
            assert set(scale["domain"]) == {row["solver"] for row in spec["data"]["values"]}


def test_every_chart_renders_inside_the_report_offline(tiny_run):
    """Snakemake's report in headless Chromium with every request outside the file
    refused: each chart page, opened from the report as a reader would, draws every one
    of its charts (an svg or canvas in each embed) and logs no error."""
    if chromium() is None:
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    from report.charts import page_specs
    report = report_html(tiny_run)
    pages = charts_of_run()
    drawn, requests, errors = {}, [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.route(re.compile(r"^(https?|wss?)://"),
                   lambda route: (requests.append(route.request.url), route.abort()))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(report.as_uri())
        page.wait_for_selector("text=0 summary", timeout=60_000)
        for rel in pages:
            open_result(page, rel)
            frame = page.frame_locator("iframe").first
            embeds = frame.locator("div.chart")
            embeds.first.wait_for(timeout=20_000)
            n = embeds.count()
            marks = frame.locator("div.chart :is(svg.marks, canvas.marks)")   # vega's drawing
            marks.nth(n - 1).wait_for(timeout=30_000)
            drawn[rel] = (n, marks.count(),
                          frame.locator("div.chart", has_text="chart failed").count())
        browser.close()
    for rel in pages:
        n_specs = len(page_specs((tiny_run / rel).read_text()))
        assert drawn[rel] == (n_specs, n_specs, 0), (rel, drawn[rel])
    assert not requests, requests
    assert not errors, errors


def test_headline_page_fits_1400_px_without_horizontal_scroll(tiny_run):
    """The summary page opens with its headline (claims' counts linking to the misses and
    the unjudged, the solver leaderboard) and, at 1400 px, neither the page nor the
    leaderboard scrolls sideways."""
    if chromium() is None:
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    summary = tiny_run / PATHS["summary_html"]
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(summary.as_uri())
        widths = page.evaluate("""() => {
            const box = document.getElementById('leaderboard-1').parentElement;
            return [document.documentElement.scrollWidth, window.innerWidth,
                    box.scrollWidth, box.clientWidth]}""")
        first = page.locator("h2").first.inner_text()
        links = page.locator(".counts a").evaluate_all("as => as.map(a => a.hash)")
        targets_found = page.evaluate("hs => hs.map(h => !!document.querySelector(h))", links)
        page.locator("#leaderboard-1 th", has_text="sgm time").click()       # sortable
        browser.close()
    assert first == "Headline"
    assert widths[0] <= widths[1] and widths[2] <= widths[3], widths
    assert links == ["#claims-pass", "#claims-miss", "#claims-unjudged"] and all(targets_found)


#: The width of the report's frame at a 1400 px window: the summary page is shown in it.
FRAME_PX = 947


def test_every_table_of_the_summary_fits_the_reports_frame(tiny_run):
    """The summary page at the width of the report's frame, every collapsed table opened:
    no table is wider than its box, no header breaks a name at an underscore, no row
    shows a raw path or claim template, and a column of numbers written with U+2212
    minus signs sorts as numbers."""
    if chromium() is None:
        pytest.skip("no Chromium on this machine (`make test` installs Debian's chromium)")
    from playwright.sync_api import sync_playwright

    summary = tiny_run / PATHS["summary_html"]
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium(), args=BROWSER_ARGS)
        page = browser.new_page(viewport={"width": FRAME_PX, "height": 900})
        page.goto(summary.as_uri())
        page.evaluate("document.querySelectorAll('details').forEach(d => d.open = true)")
        wide = page.evaluate("""() => [...document.querySelectorAll('table')]
            .map(t => [t.id, t.getBoundingClientRect().width, t.parentElement.clientWidth])
            .filter(([id, w, box]) => w > box + 0.5)""")
        headers = page.locator("th").all_inner_texts()
        cells = page.locator("td").all_inner_texts()
        page.evaluate("""() => {const t = document.createElement('table');
            t.className = 'sortable'; t.id = 'minus-sort';
            t.innerHTML = '<tr><th>x</th></tr>' + ['\u22122', '1', '\u221210', '0.5']
                .map(v => `<tr><td>${v}</td></tr>`).join('');
            document.body.appendChild(t)}""")
        page.locator("#minus-sort th").click()
        order = page.locator("#minus-sort td").all_inner_texts()
        width = page.evaluate("document.documentElement.scrollWidth")
        browser.close()
    assert not wide, wide
    assert width <= FRAME_PX
    assert not [h for h in headers if "_" in h], headers
    assert not [c for c in cells if re.search(r"\{[a-z_]+\}", c)]
    assert order == ["\u221210", "\u22122", "0.5", "1"]


def test_every_claim_reads_as_a_title_with_its_details_in_columns(tiny_run):
    """Every claim of the run: a title of at most TITLE_MAX characters; the scene, level,
    conditions, measured value, bar, source and reason in columns of their own; no
    placeholder of a claim without data."""
    from report.claims import TITLE_MAX

    claims = pd.read_csv(tiny_run / PATHS["summary_claims"], keep_default_na=False)
    assert claims["claim"].str.len().max() <= TITLE_MAX
    assert {"scene", "level", "parameters", "measured", "bar", "thesis", "reason"} <= set(
        claims.columns)
    assert (claims["parameters"] != "").mean() > 0.5 and (claims["level"] != "").any()
    for column in ("claim", "level", "parameters"):
        bad = claims.loc[claims[column].str.contains(r"\{|= -|\bnan\b|level -"), column]
        assert bad.empty, list(bad)


def test_every_unjudged_claim_gives_its_reason(tiny_run):
    claims = pd.read_csv(tiny_run / PATHS["summary_claims"], keep_default_na=False)
    unjudged = claims[claims["result"] == "n/a"]
    assert len(unjudged) and (unjudged["reason"].str.len() > 10).all()
    assert (claims.loc[claims["result"] != "n/a", "reason"] == "").all()


def test_interrupted_run_resumes_without_redoing_finished_jobs(resumed_run):
    cwd, log, after_interrupt, broken, resumed, wanted = resumed_run
    # the held job's four inputs had finished, the held job had not
    laplace_runs = {cwd / PATHS["laplace_runs"].format(case=case, side=side)
                    for case in ("sin10x", "linear") for side in ("coarse", "fine")}
    assert laplace_runs <= after_interrupt.keys(), sorted(map(str, after_interrupt))
    assert cwd / PATHS["laplace_rates"] not in after_interrupt
    assert not broken, f"half-written results after the interrupt: {broken}"
    assert resumed.returncode == 0, (resumed.stdout + resumed.stderr)[-4000:]
    redone = [str(p) for p, mtime in after_interrupt.items()
              if p.exists() and p.stat().st_mtime_ns != mtime]
    assert not redone, f"finished results rebuilt after the resume: {redone}"
    assert not [p for p in (cwd / "results").rglob(f"*{PARTIAL}*")]
    assert len(wanted) >= 20 and not [f for f in wanted if not (cwd / f).exists()]


def test_two_runs_agree_apart_from_timing_columns(tiny_run, resumed_run):
    """Seeded and deterministic: every table a solving job wrote in the plain run equals
    the resumed run's, bit for bit, except what measures time or memory
    (tests/compare_results.py); the resumed run makes no table the plain run lacks."""
    cwd, *_, wanted = resumed_run
    outputs = {Path(f) for f in wanted}
    made = tables(tiny_run)
    solved = {p for p in made if outputs & {p, *p.parents}}
    assert len(solved) >= 20 and len(made - solved) >= 10
    assert tables(cwd) == solved
    assert not differences(tiny_run, cwd, only=solved)
