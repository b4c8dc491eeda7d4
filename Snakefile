# Regenerates every table and figure of the suite.
#   snakemake --cores 2                                           (quick scale, minutes)
#   snakemake --cores 2 --configfile workflows/config/full.yaml   (the thesis's sizes, hours)
# Studies, their outputs and every path template are declared once in workflows/studies.py;
# each study's rules live in workflows/<study>.smk and run on the scenes its config lists.
import os
import sys

from snakemake.utils import validate

from workflows.studies import (PATHS, adaptive_args, adaptive_variant_file, all_targets,
                               bench_path, check_config, log_path, scenes_of, set_args,
                               thesis_table)

configfile: "workflows/config/quick.yaml"
validate(config, "workflows/config.schema.yaml")
check_config(config)   # scenes exist, problems and parameters valid, variant names known

PY = sys.executable  # the interpreter snakemake runs under (the venv's, via `make run`)
ENV = "envs/contactbench.yaml"


include: "workflows/laplace.smk"
include: "workflows/contact_solution.smk"
include: "workflows/solver_comparison.smk"
include: "workflows/augmented_projection.smk"
include: "workflows/adaptive.smk"

rule all:
    input:
        all_targets(config)
    default_target: True
