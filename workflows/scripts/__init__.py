"""The suite's benchmark scripts (``python workflows/scripts/bench_*.py``; ``make bench``).

Importing the package keeps netgen's meshes where ``$CONTACTBENCH_CACHE_DIR`` names
(:mod:`workflows.mesh_store`).
"""
from workflows.mesh_store import keep_meshes_from_environment

keep_meshes_from_environment()
