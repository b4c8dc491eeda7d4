"""The numerical kernels the solver modules share, frictionless beside frictional; none
defines a ``SOLVER`` and the registry does not look here (it skips sub-packages).

Frictionless:

* :mod:`solvers.kernels.cholesky` -- sparse Cholesky of ``A`` (MKL PARDISO, SuperLU where
  MKL is absent), partial solves on the contact support, the floating bodies' factor;
* :mod:`solvers.kernels.multigrid` -- ``A-hat`` (thesis (8.18)): V-cycles by smoothed
  aggregation or on the refinement hierarchy, semicoarsening, Lanczos bounds;
* :mod:`solvers.kernels.schur` -- ``S-hat``, the preconditioners of the Schur complement
  (thesis Sect. 8.5) for the augmented projection;
* :mod:`solvers.kernels.face` -- projection onto the face of an active set (projected
  PCG);
* :mod:`solvers.kernels.active_set` -- the primal-dual active-set update (Hintermüller,
  Ito and Kunisch);
* :mod:`solvers.kernels.contact_box` -- nodal constraints as bounds on single unknowns
  (Krause and Wohlmuth's change of variables), tangential rows as coordinates;
* :mod:`solvers.kernels.block_gs` -- the compiled node-block Gauss-Seidel sweeps of
  TNNMG;
* the pieces of truncated nonsmooth Newton multigrid (:mod:`solvers.tnnmg`):
  :mod:`solvers.kernels.tnnmg_system` (the box-transformed system, its node-block
  smoother, a Tresca step's term), :mod:`solvers.kernels.tnnmg_correction` (the truncated
  V-cycle, CG on a face), :mod:`solvers.kernels.tnnmg_line_search` (projection and line
  search);
* :mod:`solvers.kernels.scaling` -- the diagonal rescaling the QP libraries are handed.

Frictional:

* :mod:`solvers.kernels.tresca` -- the exact reference of a Tresca step, the load path
  and Coulomb's fixed point;
* :mod:`solvers.kernels.tnnmg_tresca` -- what TNNMG does differently on a Tresca step (the
  nonsmooth line searches, the slip curvature, CG on a 2D step's faces).

Numerics only: nothing here writes a file (checked by the tests).
"""
