# Regenerates every table and figure of the suite.
#   snakemake --cores 2                      (quick scale, minutes)
#   snakemake --cores 2 --config scale=full  (the thesis's sizes, hours)
# Each study lives in workflows/<study>.smk; workflows/studies.py lists its outputs.
import sys

import yaml
from workflows.studies import STUDIES

SCALE = config.get("scale", "quick")
if SCALE not in ("quick", "full"):
    raise ValueError(f"config 'scale': {SCALE!r} is not allowed; allowed: quick, full")
with open(f"workflows/config/{SCALE}.yaml") as fh:
    CFG = yaml.safe_load(fh)
PY = sys.executable  # the interpreter snakemake runs under (the venv's, via `make run`)

include: "workflows/laplace.smk"
include: "workflows/circle_square.smk"

rule all:
    input:
        [out for study in STUDIES.values() for out in study.outputs]
