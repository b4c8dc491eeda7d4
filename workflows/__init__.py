"""The edges of the suite, where files, clocks and printing live.

:mod:`workflows.studies` declares each study and its output paths in one module; the
Snakemake rules (``*.smk``) and :mod:`workflows.cli` read them back. The scripts the rules
call are in :mod:`workflows.scripts`; atomic writes and provenance in
:mod:`workflows.io`.
"""
