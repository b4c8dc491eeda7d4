"""The progress line per running study (workflows/progress.py)."""
from __future__ import annotations

import io
import json
import subprocess
import sys
import threading
import time

import yaml

from workflows import progress


def test_a_study_bar_publishes_its_state_and_removes_it_when_done(tmp_path, monkeypatch):
    config = tmp_path / "scale.yaml"
    config.write_text(yaml.safe_dump({"resources": {"exact_reference": {"mem_mb": 500,
                                                                        "runtime": 7}}}))
    monkeypatch.setenv("CONTACTBENCH_CONFIGFILE", f"{tmp_path / 'none.yaml'},{config}")
    out = tmp_path / "results" / "circle_square" / "exact_reference_runs.csv"
    bar = progress.study_progress(total=4, rule="exact_reference", out=out, file=io.StringIO())
    bar.set_postfix_str("level 2: kkt")
    bar.update()
    path = tmp_path / "results/logs/progress/exact_reference/circle_square-exact_reference_runs.json"
    state = json.loads(path.read_text())
    assert (state["done"], state["total"], state["what"], state["declared_min"]) == (
        1, 4, "level 2: kkt", 7.0)
    [line] = progress.progress_lines(tmp_path, now=state["started"] + 90)
    assert line == ("progress: exact_reference circle_square-exact_reference_runs  1/4  "
                    "level 2: kkt  1.5 min (declared 7 min)")
    bar.close()
    assert not path.exists() and progress.progress_lines(tmp_path) == []


def test_iterating_counts_and_a_dead_job_is_not_reported(tmp_path):
    out = tmp_path / "results" / "runs" / "sin10x_fine.csv"
    seen = []
    for k in progress.study_progress(range(3), rule="laplace_errors", out=out,
                                     file=io.StringIO()):
        [state] = [json.loads(p.read_text()) for p in
                   (tmp_path / "results/logs/progress").glob("*/*.json")]
        seen.append(state["done"])
    assert seen == [0, 1, 2]
    assert not list((tmp_path / "results/logs/progress").glob("*/*.json"))
    # a job killed before its bar closed leaves its file; a process that is gone is not shown
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = tmp_path / "results/logs/progress/laplace_errors/runs-linear_fine.json"
    stale.parent.mkdir(parents=True, exist_ok=True)
    stale.write_text(json.dumps({"rule": "laplace_errors", "job": "runs-linear_fine",
                                 "pid": int(dead), "started": time.time(), "done": 1,
                                 "total": 5, "what": ""}))
    assert progress.progress_lines(tmp_path) == []
    progress.clear(tmp_path)
    assert not stale.exists()


def test_the_reporter_prints_the_running_studies(tmp_path):
    """The reporter's loop: sleep, report; its second sleep hands the output over."""
    stream, reported = io.StringIO(), threading.Event()
    calls = []

    def sleep(seconds):
        calls.append(seconds)
        if len(calls) == 2:           # one report done: hand over, then hold the thread
            reported.set()
            threading.Event().wait()

    bar = progress.StudyProgress(total=2, rule="solver_comparison", job="circle_square-L2",
                                 root=tmp_path, file=io.StringIO())
    thread = progress.start_reporter(tmp_path, every=60.0, stream=stream, sleep=sleep)
    assert reported.wait(timeout=600) and thread.daemon and calls == [60.0, 60.0]
    assert stream.getvalue().startswith("progress: solver_comparison circle_square-L2  0/2  ")
    bar.close()
