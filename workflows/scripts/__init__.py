"""The workflow's scripts, one per rule (``python -m workflows.scripts.<name>``).

Importing the package keeps netgen's meshes where ``$CONTACTBENCH_CACHE_DIR`` names
(:mod:`workflows.mesh_store`): the Snakefile sets it, so a run meshes each geometry once.
"""
from workflows.mesh_store import keep_meshes_from_environment

keep_meshes_from_environment()
