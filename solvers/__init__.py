"""Contact solvers, one module each (``SOLVER = SolverSpec(...)``), all behind
:mod:`solvers.interface`, which verifies every answer with the same KKT check.

Machinery shared by solvers lives in modules without a ``SOLVER``
(:mod:`solvers.multigrid`, :mod:`solvers.face`, :mod:`solvers.schur`, ...) or with a leading underscore (:mod:`solvers._scaling`).
Numerics only: nothing here writes a file (checked by the tests).
"""
