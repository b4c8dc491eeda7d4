# Two entry points for a newcomer (see README):
#   make run   -- set up .venv and regenerate every table and figure at the quick scale
#   make test  -- set up .venv and run the test suite
# Everything else is a helper for those two. The packages are installed by uv (pinned in
# constraints.txt, the same versions pip would take, in seconds instead of minutes), their
# bytecode compiled as pip does (without it every process of a run compiles its imports
# anew: seconds each); where uv cannot install them, pip does.

PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
SCALE  ?= quick
CORES  ?= 2
PROFILE ?= workflows/profiles/default
REPORT := results/report.html
# Debian's Chromium, for the test that opens the HTML report in a real browser
CHROMIUM ?= /usr/bin/chromium

# PETSc and MPI for the distributed solver (solvers/petsc_tao.py): Debian's packages for
# the system Python (python3-petsc4py is built against its numpy, so the solve runs as
# its own MPI job); without apt-get, or where it cannot install, the petsc_tao runs and
# tests are skipped with the reason (docs/guide/distributed.md)
PETSC_PACKAGES := python3-petsc4py python3-mpi4py mpi-default-bin
# Siconos (the frictional-contact community's solvers) and h5py for the system Python: its
# solvers run as their own process (solvers/siconos.py), and the tests solve the exported
# fclib files with it, an independent code (tests/siconos_fclib.py); without apt-get, or
# where it cannot install, those runs and tests are skipped with the reason
SICONOS_PACKAGES := python3-siconos python3-h5py

.PHONY: setup browser petsc siconos run full test bench docs plan clean

$(BIN)/contactbench: pyproject.toml constraints.txt
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; set PYTHON=/path/to/python3.11"; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt uv
	$(BIN)/uv pip install --python $(BIN)/python --quiet --compile-bytecode -c constraints.txt -e '.[test]' \
	|| { echo "note: uv could not install the packages; pip installs them instead (slower)"; \
	     $(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'; }
	@touch $@

# the suite's own bytecode too (an editable install leaves it to each process, which cannot
# write it where PYTHONDONTWRITEBYTECODE is set: every job, test and command would compile
# its imports anew); only what changed since the last setup is compiled again
PACKAGES := problems solvers workflows report reference

setup: $(BIN)/contactbench
	@$(BIN)/python -m compileall -q -j 0 $(PACKAGES)

# the regeneration, then Snakemake's HTML report of it (the summary page first)
run: setup petsc siconos
	$(BIN)/snakemake --profile $(PROFILE) --cores $(CORES) --configfile workflows/config/$(SCALE).yaml
	$(BIN)/snakemake --profile $(PROFILE) --cores $(CORES) --configfile workflows/config/$(SCALE).yaml --report $(REPORT)
	@echo "report: $(REPORT)"

full: setup
	$(MAKE) run SCALE=full

browser: $(CHROMIUM)

$(CHROMIUM):
	@command -v apt-get >/dev/null 2>&1 || { echo "error: $(CHROMIUM) not found and no apt-get; install Chromium and set CHROMIUM=/path/to/chromium"; exit 2; }
	apt-get install -y --no-install-recommends chromium || { apt-get update && apt-get install -y --no-install-recommends chromium; }

# Debian packages for the system Python, installed where apt-get can: $(1) the packages,
# $(2) what is skipped without them (a note, never a failure)
define apt_install
	@if ! command -v apt-get >/dev/null 2>&1; then \
		echo "note: no apt-get: $(1) not installed, $(2)"; \
	elif dpkg -s $(1) >/dev/null 2>&1; then :; \
	else \
		apt-get install -y --no-install-recommends $(1) \
		|| { apt-get update && apt-get install -y --no-install-recommends $(1); } \
		|| echo "note: $(1) could not be installed, $(2)"; \
	fi
endef
PETSC_SKIPPED := the petsc_tao runs are skipped (docs/guide/distributed.md)
SICONOS_SKIPPED := the siconos_nsgs and siconos_newton runs are skipped (docs/guide/friction.md)

petsc:
	$(call apt_install,$(PETSC_PACKAGES),$(PETSC_SKIPPED))

siconos:
	$(call apt_install,$(SICONOS_PACKAGES),$(SICONOS_SKIPPED))

# the solver tests, run once more under every other OpenBLAS kernel the CPU can run
# (tests/blas_kernels.py), each with another of MKL's code paths for PARDISO (MKL_CBWR; the
# OpenBLAS kernel does not reach it): rounding must not decide a solve. The reruns leave out
# the tests marked `slow` (mostly a finer level of a solve whose coarser levels run there).
# The random frictional family first: spread over processes, its file (the longest) starts at once.
SOLVER_TESTS := tests/test_friction_random.py tests/test_rounding.py tests/test_solvers.py \
	tests/test_semismooth_newton.py tests/test_augmented_projection.py tests/test_cholesky.py \
	tests/test_qp.py tests/test_two_body.py tests/test_tnnmg.py tests/test_layered_multigrid.py \
	tests/test_petsc_tao.py tests/test_degenerate.py tests/test_two_pass.py tests/test_friction.py \
	tests/test_mortar.py tests/test_friction_ssn.py tests/test_mortar_3d.py tests/test_mortar_p2.py \
	tests/test_friction_registry.py tests/test_friction_tnnmg.py tests/test_friction_tnnmg_3d.py \
	tests/test_friction_3d_solvers.py tests/test_friction_libraries.py tests/test_friction_facets.py \
	tests/test_problem_set_friction.py tests/test_siconos.py tests/test_certificate_friction.py \
	tests/test_stabilised.py tests/test_circle_square.py tests/test_hertz_mindlin.py \
	tests/test_hard_cases.py::test_tolerances_are_scale_free \
	tests/test_cli.py::test_every_solver_runs_through_the_cli

# the tests spread over one process per core (pytest-xdist; at most 8 by default), a test file's tests in one
# process (its fixtures built once), each process with one BLAS thread; the solver tests
# then once more under each other kernel: with several, one process per kernel side by side,
# each running all of them (`--dist each`; a failure names its process by the kernel); with
# one (an AVX2 machine's Sandybridge), spread over one process per core as above
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); [ $$n -gt 8 ] && n=8; echo $$n)
ONE_THREAD := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

test: setup browser petsc siconos
	$(ONE_THREAD) CONTACTBENCH_CHROMIUM=$(CHROMIUM) $(BIN)/python -m pytest -q -n $(TEST_WORKERS) \
		--dist loadfile --no-loadscope-reorder --durations=10
	@kernels="$$($(BIN)/python tests/blas_kernels.py)" || exit 1; \
	[ -n "$$kernels" ] || { echo "no other OpenBLAS kernel to run the solver tests under"; exit 0; }; \
	set -- AVX2 COMPATIBLE; tx=""; \
	for k in $$kernels; do \
		cbwr="$${1:-COMPATIBLE}"; [ $$# -gt 0 ] && shift; \
		tx="$$tx --tx popen//id=$$k//env:OPENBLAS_CORETYPE=$$k//env:MKL_CBWR=$$cbwr"; \
	done; dist="--dist each"; how="side by side"; \
	if [ "$$(echo $$kernels | wc -w)" -eq 1 ]; then \
		tx="--tx $(TEST_WORKERS)*popen//env:OPENBLAS_CORETYPE=$$kernels//env:MKL_CBWR=AVX2"; \
		dist="--dist loadfile"; how="in $(TEST_WORKERS) processes"; \
	fi; \
	echo "== the solver tests again under the OpenBLAS kernels $$kernels, $$how"; \
	$(ONE_THREAD) $(BIN)/python -m pytest -q -p no:cacheprovider $$dist --no-loadscope-reorder $$tx \
		-m "not slow" \
		$(SOLVER_TESTS)

# pytest-benchmark history in .benchmarks/ (not committed): each run saved and compared
# with the previous one
bench: setup
	$(BIN)/python -m pytest -q tests --benchmark-enable --benchmark-only --benchmark-autosave \
		$$(ls .benchmarks/*/*.json >/dev/null 2>&1 && echo --benchmark-compare)

# the documentation site, warnings as errors (the scene, solver, CLI and API pages are
# generated from the code at every build: docs/_ext/registry_pages.py)
docs: setup
	$(BIN)/python -m sphinx -b html -W --keep-going docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

# huge.yaml's resources predicted from the benchmark files of a quick and a full run
# (workflows/planning.py): make plan QUICK_RUN=<checkout of a quick run> FULL_RUN=<...>
QUICK_RUN ?= .
FULL_RUN ?= .
plan: setup
	$(BIN)/python -m workflows.planning --target workflows/config/huge.yaml --measured \
		workflows/config/quick.yaml=$(QUICK_RUN)/results/benchmarks \
		workflows/config/full.yaml=$(FULL_RUN)/results/benchmarks

clean:
	rm -rf results/*/ .snakemake
