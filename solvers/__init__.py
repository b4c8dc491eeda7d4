"""Contact solvers, one module each (``SOLVER = SolverSpec(...)``), all behind
:mod:`solvers.interface`, which verifies every answer with the same KKT check.

Beside the solver modules: the interface (:mod:`solvers.interface`, the registry and
``solve``), the reference policy (:mod:`solvers.reference`), the verification
(:mod:`solvers.certificate`) and the shared types (:mod:`solvers.base`). The numerical
kernels the solvers share live in :mod:`solvers.kernels` (no ``SOLVER``; the registry
skips sub-packages and modules with a leading underscore, such as the PETSc worker
script :mod:`solvers._petsc_tao_worker`). Numerics only: nothing here writes a file
(checked by the tests).
"""
