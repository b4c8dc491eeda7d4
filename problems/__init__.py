"""Scenes of the suite, one module each (see :mod:`problems.spec`).

Shared finite-element and contact machinery lives in the subpackage
:mod:`problems.fem`; it is not a problem and the registry skips it.
"""
