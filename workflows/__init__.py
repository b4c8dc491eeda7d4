"""Snakemake rules, configurations and the scripts the rules call (and the CLI)."""
