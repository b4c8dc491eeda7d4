"""Alg. 8.4 towards incompressibility: n_o against Poisson's ratio (a table of the
hard-case study).

For each scene (``--scenes``, each at ``--level``) and each ``nu`` in ``--nus`` (both
bodies), the augmented projection (``solvers/augmented_projection.py``) runs twice at the
``mid`` tolerance (verified KKT and certified bound <= 1e-6):

* ``robust`` -- its defaults: ``A-hat`` a Chebyshev polynomial in the V-cycle whose degree
  comes from the measured ``kappa(V A)`` (:func:`solvers.kernels.multigrid.scaled_vcycle`), and
  ``S-hat`` multilevel while it stays equivalent to ``S_in``, else ``S_in`` itself;
* ``vcycle`` -- the thesis's pair as the augmented-projection study runs it: one V-cycle as
  ``A-hat`` (degree 1) and the multilevel ``S-hat``, capped at ``--max-iter`` outer steps.

Per run: status, n_o, the Chebyshev degree, ``kappa(V A)`` of the plain V-cycle (the
corrected Ritz estimate), ``gamma_bar``, the ``S-hat`` kind and ``kappa(S-hat^-1 S_in)``,
V-cycles, setup and solve time. One process, one solve after the other.

Example::

    python -m workflows.studies.hard_cases.run --scenes circle_square cube_sphere \\
        --level 1 --nus 0.3 0.45 0.49 0.499 0.4999 --out results/hard_cases/incompressibility.csv
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from tqdm import tqdm

from problems.spec import ParameterError, problems
from solvers.interface import solve
from workflows.io import write_csv
from workflows.progress import study_progress

#: The two configurations of the table: the solver's defaults, and the thesis's pair.
VARIANTS = {"robust": {}, "vcycle": {"ahat.degree": 1, "schur": "multilevel"}}


def run(qp, variant: str, max_iter: int, time_limit: float) -> dict:
    """One Alg. 8.4 solve of ``qp`` in ``variant``: its row."""
    t0 = time.perf_counter()
    res = solve(qp, "augmented_projection", tol="mid", max_iter=max_iter,
                time_limit=time_limit, **VARIANTS[variant])
    s = res.stats
    return {"variant": variant, "status": res.status, "n_outer": res.iterations,
            "ahat_degree": s.get("ahat_degree", np.nan),
            "kappa_vcycle": s.get("kappa_vcycle", np.nan), "gamma_bar": s.get("gamma_bar"),
            "schur_kind": s.get("schur_kind"), "kappa_SinvSin": s.get("kappa_SinvSin"),
            "n_vcycles": s.get("n_vcycles"), "t_setup": res.setup_time,
            "t_solve": res.solve_time, "wall_time": time.perf_counter() - t0,
            "kkt_max": res.kkt.max if res.kkt is not None else np.nan,
            "message": res.message[:200]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", required=True, help="registered contact problems")
    parser.add_argument("--level", type=int, required=True, help="mesh level of every scene")
    parser.add_argument("--nus", type=float, nargs="+", required=True,
                        help="Poisson's ratios of both bodies (each in the scene's range)")
    parser.add_argument("--max-iter", type=int, default=2000, help="outer steps per solve (>= 1)")
    parser.add_argument("--time-limit", type=float, default=120.0,
                        help="seconds per solve (> 0)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    registry = problems()
    contact = sorted(n for n, s in registry.items() if s.kind == "contact")
    bad = [s for s in args.scenes if s not in contact]
    if bad:
        parser.error(f"argument --scenes: {bad} not allowed; allowed: {', '.join(contact)}")
    if args.max_iter < 1:
        parser.error(f"argument --max-iter: {args.max_iter} is not allowed; allowed: >= 1")
    if args.time_limit <= 0:
        parser.error(f"argument --time-limit: {args.time_limit} is not allowed; allowed: > 0")
    cases = []
    for name in args.scenes:
        spec = registry[name]
        try:
            level = spec.check_level(args.level)
            cases += [(name, level, nu, spec.options(nu1=nu, nu2=nu)) for nu in args.nus]
        except ParameterError as err:
            parser.error(str(err).replace("parameter 'nu1'", "argument --nus")
                         .replace("parameter 'level'", "argument --level"))
    rows = []
    for name, level, nu, params in study_progress(
            cases, rule="hard_cases_incompressibility", out=args.out, desc="incompressibility",
            unit="scene"):
        qp = registry[name].build(level, params)
        for variant in VARIANTS:
            row = run(qp, variant, args.max_iter, args.time_limit)
            rows.append({"scene": name, "level": level, "dim": qp.dim, "N": qp.n_nodes,
                         "n": qp.n, "m": qp.m, "nu": nu, **row})
            tqdm.write(f"{name} nu={nu:g} {variant}: {row['status']} n_o={row['n_outer']} "
                       f"degree {row['ahat_degree']} ({row['wall_time']:.1f} s)")
    write_csv(args.out, pd.DataFrame(rows))


if __name__ == "__main__":
    main()
