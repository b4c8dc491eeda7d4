# Regenerates every table and figure of the suite.
#   snakemake --cores 2                                           (quick scale, minutes)
#   snakemake --cores 2 --configfile workflows/config/full.yaml   (the thesis's sizes, ~1.5 h)
# A study is one module of workflows/studies/ (its paths, outputs, thesis items, config
# checks), discovered; its rules live in the rule file it names (workflows/<study>.smk),
# included below, and run on the scenes its config lists.
import hashlib
import json
import os
import shlex
import sys

from snakemake.utils import validate

from solvers.interface import solver_set
from workflows.io import SOLVER_SET_ENV, run_solver_set, sweep_results
from workflows.progress import clear as clear_progress, start_reporter
from workflows.settings import SCHEMA

from workflows.studies import (PATHS, STUDIES, all_targets, bench_path, check_config,
                               coarser_levels, log_path, rule_resources, scenes_of,
                               scenes_with_families, set_args, summary_items, test_set_of,
                               thesis_table)

# the quick scale unless --configfile names another (merging quick.yaml under full.yaml or
# tiny.yaml would leave quick's scenes in them)
if not workflow.overwrite_configfiles:
    configfile: os.path.join(workflow.basedir, "workflows/config/quick.yaml")
report: "report/workflow.rst"
# the test set's families are scenes too (workflows/config/test_sets/): typed once there
config["scenes"] = scenes_with_families(config)
validate(config, str(SCHEMA))   # fills in the schema's defaults (workflows/settings.py)
check_config(config)   # scenes exist, problems and parameters valid, variant names known

# provenance of every result names the config; corrupted results and partial files of a
# killed run are removed here, so that they are rebuilt (workflows/io.py)
CONFIG_SHA256 = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()
# the solver set is fixed here, when the run starts: a plug-in installed or removed while it
# runs changes no study; every result's provenance records the set (plug-ins with package
# and version). A job that parses this file again inherits the set of its run.
SOLVER_SET = run_solver_set() or solver_set()
os.environ[SOLVER_SET_ENV] = json.dumps(SOLVER_SET, sort_keys=True)
shell.prefix(f"export CONTACTBENCH_CONFIGFILE={','.join(map(str, workflow.configfiles))} "
             f"CONTACTBENCH_CONFIG_SHA256={CONFIG_SHA256} "
             f"{SOLVER_SET_ENV}="      # the prefix is formatted once more: braces doubled
             + shlex.quote(os.environ[SOLVER_SET_ENV]).replace("{", "{{").replace("}", "}}")
             + "; ")
for removed in sweep_results("results"):
    print(f"removed a corrupted or partial result, to be rebuilt: {removed}", file=sys.stderr)

# one line per running study every minute (which job, how far, the declared runtime)
onstart:
    clear_progress()
    start_reporter()

# the configuration's name(s), e.g. "quick", for the summary page
SCALE = "+".join(os.path.splitext(os.path.basename(str(f)))[0]
                 for f in workflow.configfiles) or "command-line"

PY = sys.executable  # the interpreter snakemake runs under (the venv's, via `make run`)
ENV = "envs/contactbench.yaml"


# every study's rule file (its own helpers it imports from its study module), then the
# summary page over them
for _study in STUDIES.values():
    include: os.path.join("workflows", _study.rule_file)
include: "workflows/summary.smk"

rule all:
    input:
        all_targets(config), PATHS["summary_html"], PATHS["summary_claims"]
    default_target: True
