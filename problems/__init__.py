"""Scenes of the suite, one module each, and the neutral core they share.

* :mod:`problems.spec` -- plug-in specs (``PROBLEM = ProblemSpec(...)``), parameters
  and component options, declared once and validated;
* :mod:`problems.qp` -- the algebraic contact problem (:class:`problems.qp.ContactQP`
  with typed mesh, contact and multilevel data), its KKT residuals and energy error;
  both scenes and solvers import it;
* :mod:`problems.fem` -- finite-element and contact machinery (elasticity, Alg. 7.1,
  meshes, surface hierarchies, two-body assembly, fields); not a problem, the
  registry skips it.

Numerics only: nothing here writes a file (checked by the tests).
"""
