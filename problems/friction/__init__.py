"""Friction on the constrained rows: Tresca and Coulomb, 2D and 3D, isotropic or faceted.

* :mod:`problems.friction.data` -- what defines a frictional step: the laws, the
  :class:`~problems.friction.data.Friction` data a :class:`problems.qp.ContactQP` carries
  (tangential rows, slip bounds, previous state, load path) and the allowed facet counts;
* :mod:`problems.friction.polygon` -- the faceted law's inscribed regular ``k``-gon:
  vertices, support function, gauge, projection and its regions;
* :mod:`problems.friction.forms` -- one Tresca step in the standard forms of the QP and
  conic libraries (split QP, facet QP, second-order cone program, epigraph) and the maps
  of their multipliers;
* :mod:`problems.friction.residuals` -- how a frictional answer is judged: the KKT
  residuals of a Tresca step and its energy;
* :mod:`problems.friction.random_family` -- frictional problems drawn at random, seeded
  (the robustness tests' family).

Not a problem: the registry skips sub-packages.
"""
