"""Contact solvers, one module each, all behind :mod:`solvers.interface`."""
