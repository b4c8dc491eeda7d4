"""Table and figure builders: they read result files and write tables and figures
(atomically); :mod:`report.rates` holds every fitted rate and slope; ``captions/``
the captions of the HTML report."""

import matplotlib

# every figure is drawn to a file: the headless backend, set once for the report
matplotlib.use("Agg")
