"""Rounding must not decide a solve.

Every registered solver on the random two-body family over 60 seeds and on copies of
each problem whose data (A, f, B, g) are perturbed by a relative 1e-14 -- the size of
the difference between two BLAS kernels' results. CI runs this file a second time under
another OpenBLAS kernel than the machine's own (``.ci/run``).

What is asserted, per solver:
- the suite's own solvers, which stop on the verification (the exact PDAS, the
  semismooth Newton method, the augmented projection, TNNMG), converge on every problem
  they take and every claim of theirs verifies; a problem is skipped on its structure
  alone (TNNMG takes only rows with a node of their own: one of the 60 here; its
  rounding test on the scenes is in ``test_tnnmg.py``);
- a run that verifies is as close to the exact reference as its certified bound says
  (the certificate is checked against an independent solve, for every solver);
- a problem and its perturbed copy give the same solution to the tolerance, for every
  run that verifies on both.
The library solvers' own stopping tests are looser than the KKT conditions (the solver
comparison's page of the docs): their claims may be refuted by the verification, which is what it
is for; they are held to the second and third points only.
"""
from __future__ import annotations

import numpy as np
import pytest

from problems.kkt import energy_error
from problems.qp import ContactQP
from solvers.interface import STATUSES, TOLERANCES, solve, solvers
from test_solvers import two_body_qp
from agreement import within_certificate

SEEDS = range(60)
#: Solvers that stop on the suite's verification: their claims are never refuted.
SELF_VERIFYING = ("exact", "newton", "thesis")


def perturbed(qp: ContactQP, seed: int, rel: float = 1e-14) -> ContactQP:
    """``qp`` with every stored entry of A (kept symmetric), f, B and g changed by a
    relative ``rel`` (uniform, seeded)."""
    rng = np.random.default_rng(10_000 + seed)
    A = qp.A.tocsr(copy=True)
    A.data *= 1.0 + rel * rng.uniform(-1.0, 1.0, A.nnz)
    A = (0.5 * (A + A.T)).tocsr()
    B = qp.B.tocsr(copy=True)
    B.data *= 1.0 + rel * rng.uniform(-1.0, 1.0, B.nnz)
    f = qp.f * (1.0 + rel * rng.uniform(-1.0, 1.0, qp.n))
    g = qp.g * (1.0 + rel * rng.uniform(-1.0, 1.0, qp.m))
    return ContactQP(A=A, f=f, B=B, g=g, name=qp.name + "-perturbed")


@pytest.fixture(scope="module")
def family():
    """``[(qp, perturbed copy, exact reference of qp)]`` over :data:`SEEDS`."""
    out = []
    for seed in SEEDS:
        qp = two_body_qp(seed=seed)
        ref = solve(qp, "pdas", "high")
        assert ref.status == "converged", (seed, ref.message)
        out.append((qp, perturbed(qp, seed), ref))
    return out


def test_the_perturbation_is_of_rounding_size(family):
    qp, copy, _ = family[0]
    assert 0 < abs(copy.A - qp.A).max() <= 2e-14 * abs(qp.A).max()
    assert 0 < np.abs(copy.g - qp.g).max() <= 1e-14 * np.abs(qp.g).max()


@pytest.mark.parametrize("name", sorted(solvers()))
def test_rounding_does_not_decide(family, name):
    spec = solvers()[name]
    tol = TOLERANCES["mid"]
    refuted, failures, taken = 0, [], 0
    for qp, copy, ref in family:
        runs = [solve(problem, name, "mid") for problem in (qp, copy)]
        # a solver that cannot take a problem (TNNMG: rows that share a node) skips it on
        # its structure, never on rounding: both copies alike
        assert (runs[0].status == "skipped") == (runs[1].status == "skipped"), qp.name
        taken += runs[0].status != "skipped"
        for problem, run in zip((qp, copy), runs):
            assert run.status in STATUSES, (problem.name, run.status)
            if run.status == "skipped":
                assert not spec.check(problem)[0] and run.message.startswith("skipped: ")
                continue
            if spec.role in SELF_VERIFYING and run.status != "converged":
                failures.append(f"{problem.name}: {run.status}: {run.message}")
            if run.claimed_status == "converged" and run.status != "converged":
                refuted += 1
            if run.status == "converged":
                # the certified bound holds against the exact reference (its own error
                # is ~1e-15 and covered by the bound's floor)
                err = energy_error(qp, run.u, ref.u)
                assert within_certificate(err, run.gap.certified_bound, run.gap.floor), \
                    (problem.name, err, run.gap.certified_bound)
        if all(r.status == "converged" for r in runs):
            assert energy_error(qp, runs[1].u, runs[0].u) <= 2 * tol, qp.name
    assert not failures, "\n".join(failures)
    if not taken and spec.handles_friction and all(
            "frictionless problem" in spec.check(qp)[1] for qp, _, _ in family):
        pytest.skip(f"{name} takes frictional problems only; the family is frictionless")
    assert taken >= 1, f"{name} skipped every problem of the family"
    if spec.role in SELF_VERIFYING:
        assert refuted == 0


def test_semismooth_newton_matches_the_exact_active_set(family):
    """Not only verified: on every problem of the family the semismooth Newton method
    ends on the exact reference's active set, in a handful of Newton steps."""
    for qp, copy, ref in family:
        for problem in (qp, copy):
            run = solve(problem, "semismooth_newton", "high")
            assert run.status == "converged", (problem.name, run.message)
            assert np.array_equal(run.p > 0, ref.p > 0), problem.name
            assert run.stats["inner_steps"] <= 2 * problem.n, problem.name


# ------------------------------------------------------ the kernels `make test` adds
def test_blas_kernels_lists_only_what_the_cpu_can_run():
    from blas_kernels import cpu_flags, other_kernels

    skylake = cpu_flags("processor : 0\nflags : fpu sse avx avx2 fma avx512f avx512cd "
                        "avx512bw avx512dq avx512vl\n")
    assert other_kernels(skylake, {"SkylakeX"}) == ["Haswell", "Sandybridge"]
    assert other_kernels(skylake, {"Haswell"}) == ["SkylakeX", "Sandybridge"]
    zen2 = cpu_flags("flags\t\t: fpu sse avx avx2 fma\n")
    assert other_kernels(zen2, {"Zen"}) == ["Haswell", "Sandybridge"]
    assert other_kernels(zen2, {"Haswell"}) == ["Sandybridge"]
    assert other_kernels(set(), {"Prescott"}) == []


def test_blas_kernels_runs_on_this_machine():
    import subprocess
    import sys
    from pathlib import Path

    out = subprocess.run([sys.executable, str(Path(__file__).with_name("blas_kernels.py"))],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    from blas_kernels import KERNELS
    assert set(out.stdout.split()) <= set(KERNELS)


def test_the_blas_kernel_is_the_one_asked_for():
    """Under ``OPENBLAS_CORETYPE`` (``make test``'s reruns of the solver tests) every
    OpenBLAS in the process (numpy's and scipy's) runs that kernel: the reruns test what
    they say they test."""
    import os

    from blas_kernels import own_kernels

    asked = os.environ.get("OPENBLAS_CORETYPE")
    if not asked:
        pytest.skip("OPENBLAS_CORETYPE is not set: the machine's own kernel")
    assert {k.lower() for k in own_kernels()} == {asked.lower()}
