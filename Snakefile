# Regenerates every table and figure of the suite.
#   snakemake --cores 2                                           (quick scale, minutes)
#   snakemake --cores 2 --configfile workflows/config/full.yaml   (the thesis's sizes, ~1.5 h)
# A study is one folder of workflows/studies/ (its declaration, settings, run steps, rules,
# captions and docs page), discovered; its rules (workflows/studies/<study>/rules.smk) are
# included below and run on the scenes its config lists.
import atexit
import hashlib
import json
import os
import shlex
import shutil
import sys
import tempfile

from snakemake.utils import validate

from solvers.interface import solver_set
from workflows.io import SOLVER_SET_ENV, run_solver_set, sweep_results
from workflows.mesh_store import CACHE_VARIABLE
from workflows.table_pages import shown_pages, shown_table
from workflows.progress import clear as clear_progress, start_reporter

from workflows.studies import (PATHS, STUDIES, all_targets, at_scale, bench_path,
                               caption_files, check_config, coarser_levels, log_path,
                               problem_set_of, rule_resources, scenes_of,
                               scenes_with_families, schema_file, set_args, summary_items,
                               thesis_table)

# the quick scale unless --configfile names another (merging quick.yaml under full.yaml or
# tiny.yaml would leave quick's scenes in them)
if not workflow.overwrite_configfiles:
    configfile: os.path.join(workflow.basedir, "workflows/config/quick.yaml")
# the sections and resources the studies declare at the config's scale (scale: quick)
config.update(at_scale(config))
# the test set's families are scenes too (workflows/config/test_sets/): typed once there
config["scenes"] = scenes_with_families(config)
# the schema: workflows/config.schema.yaml and each study's own section (its module);
# validating fills in the schema's defaults (workflows/settings.py)
with schema_file() as schema:
    validate(config, schema)
check_config(config)   # scenes exist, problems and parameters valid, variant names known

# provenance of every result names the config; corrupted results and partial files of a
# killed run are removed here, so that they are rebuilt (workflows/io.py)
CONFIG_SHA256 = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()
# the solver set is fixed here, when the run starts: a plug-in installed or removed while it
# runs changes no study; every result's provenance records the set (plug-ins with package
# and version). A job that parses this file again inherits the set of its run.
SOLVER_SET = run_solver_set() or solver_set()
os.environ[SOLVER_SET_ENV] = json.dumps(SOLVER_SET, sort_keys=True)
# netgen's meshes kept between the jobs' processes (workflows/mesh_store.py): each
# geometry meshed once per run; `make clean` or a fresh clone starts with none
MESH_CACHE = os.environ.get(CACHE_VARIABLE, os.path.abspath("results/cache/meshes"))
shell.prefix(f"export CONTACTBENCH_CONFIGFILE={','.join(map(str, workflow.configfiles))} "
             f"{CACHE_VARIABLE}={shlex.quote(MESH_CACHE)} "
             f"CONTACTBENCH_CONFIG_SHA256={CONFIG_SHA256} "
             f"{SOLVER_SET_ENV}="      # the prefix is formatted once more: braces doubled
             + shlex.quote(os.environ[SOLVER_SET_ENV]).replace("{", "{{").replace("}", "}}")
             + "; ")
for removed in sweep_results("results"):
    print(f"removed a corrupted or partial result, to be rebuilt: {removed}", file=sys.stderr)
# the HTML report opens on the run's headline (written by the summary rule) once it exists
# (after the sweep above), on the description of its sections before
_LANDING = (os.path.abspath(PATHS["summary_landing"]) if os.path.exists(PATHS["summary_landing"])
            else "report/workflow.rst")
report: _LANDING

# one line per running study every minute (which job, how far, the declared runtime)
onstart:
    clear_progress()
    start_reporter()

# the configuration's name(s), e.g. "quick", for the summary page
SCALE = "+".join(os.path.splitext(os.path.basename(str(f)))[0]
                 for f in workflow.configfiles) or "command-line"

PY = sys.executable  # the interpreter snakemake runs under (the venv's, via `make run`)
ENV = os.path.join(workflow.basedir, "workflows/envs/contactbench.yaml")


# each study's captions file split into one file per output, for report(caption=...)
_CAPTION_DIR = tempfile.mkdtemp(prefix="contactbench-captions-")
atexit.register(shutil.rmtree, _CAPTION_DIR, ignore_errors=True)
CAPTIONS = caption_files(_CAPTION_DIR)

# every study's rules (its folder's rules.smk, which imports its own helpers from the
# folder's declaration), then the summary page over them
for _study in STUDIES.values():
    include: os.path.join(_study.folder, "rules.smk")
TARGETS = all_targets(config)         # every study's outputs at this config's scale
include: "workflows/summary.smk"

rule all:
    input:
        TARGETS, rules.summary.output
    default_target: True
