"""Scenes of the suite, one module each, and the neutral core they share.

* :mod:`problems.spec` -- plug-in specs (``PROBLEM = ProblemSpec(...)``), parameters
  and component options, declared once and validated;
* :mod:`problems.qp` -- the algebraic contact problem (:class:`problems.qp.ContactQP`
  with typed mesh, contact and multilevel data); both scenes and solvers import it;
  :mod:`problems.kkt` its KKT residuals and energy error;
* :mod:`problems.friction` -- friction on the constrained rows: the
  :class:`~problems.friction.data.Friction` data a ContactQP may carry, the faceted law's
  polygon, a Tresca step's QP and cone-program forms and its KKT residuals; not a
  problem, the registry skips it;
* :mod:`problems.fem` -- finite-element and contact machinery (elasticity, Alg. 7.1,
  meshes, surface hierarchies, two-body assembly, fields); not a problem, the
  registry skips it.

Numerics only: nothing here writes a file (checked by the tests).
"""
