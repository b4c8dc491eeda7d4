"""One progress line per running study at the console.

A study script's progress bar (tqdm) goes to its job's log; at the full scale a job runs
for many minutes with nothing at the console but Snakemake's job count. So a study's bar is
a :class:`StudyProgress`: besides the log, it keeps a small JSON file per running job
(:data:`PROGRESS`: rule, what it does now, done/total, start, process id, the
rule's declared runtime), and the Snakefile's ``onstart`` starts :func:`start_reporter`,
which prints one line per running study every minute, e.g.::

    progress: augmented_projection_study circle_square  5/12  level 3: alg84  2.1 min (declared 14 min)

The file goes when the bar closes; one whose process is gone is not shown (a killed job),
and a new regeneration removes the old ones (:func:`clear`).
"""
from __future__ import annotations

import json
import os
import sys
import threading
import time
from pathlib import Path

from workflows.yaml_io import read_yaml
from tqdm import tqdm

#: The file of a running job's bar, below the working directory.
PROGRESS = "results/logs/progress/{rule}/{name}.json"
#: Seconds between two reports at the console.
REPORT_EVERY = 60.0


def declared_runtime(rule: str) -> float | None:
    """The runtime (minutes) ``rule`` declares at the running scale: the last config file
    Snakemake was given (``CONTACTBENCH_CONFIGFILE``, set by the Snakefile); None when
    run by hand."""
    files = [f for f in os.environ.get("CONTACTBENCH_CONFIGFILE", "").split(",") if f]
    for path in reversed(files):
        try:
            config = read_yaml(Path(path).read_text()) or {}
        except OSError:
            continue
        runtime = (config.get("resources") or {}).get(rule, {}).get("runtime")
        if runtime is not None:
            return float(runtime)
    return None


class StudyProgress(tqdm):
    """A tqdm bar that also publishes its state for :func:`progress_lines`.

    Parameters
    ----------
    rule : str
        The heavy rule the script runs under (``workflows.studies.HEAVY_RULES``).
    job : str
        What distinguishes this job among the rule's (e.g. the scene); the file's name.
    root : str or Path
        The directory results are written under (the working directory's ``results``).
    *args, **kwargs
        tqdm's (``total``, ``desc``, ...).
    """

    def __init__(self, *args, rule: str, job: str, root: str | os.PathLike = ".", **kwargs):
        self._file = None
        super().__init__(*args, **kwargs)
        self._file = Path(root) / PROGRESS.format(rule=rule, name=job)
        self._state = {"rule": rule, "job": job, "pid": os.getpid(), "started": time.time(),
                       "declared_min": declared_runtime(rule)}
        self._publish()

    def _publish(self) -> None:
        """Write the state (a few updates per level or solver: each one is written)."""
        if self._file is None:
            return
        state = {**self._state, "done": self.n, "total": self.total,
                 "what": str(self.postfix or "")}
        self._file.parent.mkdir(parents=True, exist_ok=True)
        tmp = self._file.with_name(f".{self._file.name}.{os.getpid()}")
        tmp.write_text(json.dumps(state))
        os.replace(tmp, self._file)

    def __iter__(self):
        # tqdm's own iteration counts in a local variable; count through update()
        try:
            for item in self.iterable:
                yield item
                self.update()
        finally:
            self.close()

    def update(self, n=1):
        out = super().update(n)
        self._publish()
        return out

    def set_postfix_str(self, s="", refresh=True):
        super().set_postfix_str(s, refresh)
        self._publish()

    def close(self):
        super().close()
        if self._file is not None:
            self._file.unlink(missing_ok=True)
            self._file = None


def study_progress(iterable=None, *, rule: str, out: str | os.PathLike, **kwargs
                   ) -> StudyProgress:
    """A study script's bar: the job named by its output (``results/<scene>/x.csv`` ->
    ``<scene>-x``), the file under the directory holding ``results``."""
    out = Path(out).resolve()
    root = next((p.parent for p in out.parents if p.name == "results"), Path.cwd())
    return StudyProgress(iterable, rule=rule, job=f"{out.parent.name}-{out.stem}", root=root,
                         **kwargs)


def _directory(root: str | os.PathLike) -> Path:
    """Where the running jobs' files live: one subdirectory per rule."""
    return Path(root) / Path(PROGRESS).parent.parent


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def progress_lines(root: str | os.PathLike = ".", now: float | None = None) -> list[str]:
    """One line per running study (its process alive), oldest first."""
    now = time.time() if now is None else now
    directory = _directory(root)
    states = []
    for path in directory.glob("*/*.json"):
        try:
            state = json.loads(path.read_text())
        except (OSError, ValueError):
            continue                      # being replaced right now
        if _alive(int(state.get("pid", -1))):
            states.append(state)
    lines = []
    for s in sorted(states, key=lambda s: s["started"]):
        minutes = (now - s["started"]) / 60
        total = f"/{s['total']}" if s.get("total") else ""
        declared = (f" (declared {s['declared_min']:g} min)" if s.get("declared_min")
                    else "")
        what = f"  {s['what']}" if s.get("what") else ""
        lines.append(f"progress: {s['rule']} {s['job']}  {s['done']}{total}{what}  "
                     f"{minutes:.1f} min{declared}")
    return lines


def clear(root: str | os.PathLike = ".") -> None:
    """Remove the progress files of an earlier regeneration (none of its jobs runs)."""
    directory = _directory(root)
    for path in directory.glob("*/*.json"):
        path.unlink(missing_ok=True)


def report(root: str | os.PathLike = ".", stream=None) -> None:
    """Print :func:`progress_lines` to ``stream`` (stderr)."""
    for line in progress_lines(root):
        print(line, file=stream or sys.stderr, flush=True)


def start_reporter(root: str | os.PathLike = ".", every: float = REPORT_EVERY,
                   stream=None, sleep=time.sleep) -> threading.Thread:
    """A daemon thread calling :func:`report` every ``every`` seconds."""
    def loop():
        while True:
            sleep(every)
            report(root, stream)

    thread = threading.Thread(target=loop, name="study progress", daemon=True)
    thread.start()
    return thread
