"""Fields of a solved contact problem as VTU (meshio), written atomically."""
from __future__ import annotations

import numpy as np

from problems.fem.elasticity import von_mises


def contact_fields(qp, result) -> dict:
    """Nodal displacement, nodal contact pressure and cell von Mises stress."""
    geo = qp.geometry
    points, cells = np.asarray(geo["points"]), np.asarray(geo["cells"])
    u = qp.full_displacement(result.u)
    pressure = np.zeros(len(points))
    if qp.contact_nodes is not None and qp.contact_mass is not None:
        pressure[qp.contact_nodes] = result.p / qp.contact_mass
    vm = von_mises(points, cells, u, geo["E_cell"], geo["nu_cell"])
    return {"points": points, "cells": cells, "displacement": u, "contact_pressure": pressure,
            "von_mises": vm, "body": np.asarray(geo.get("body_of_node", np.zeros(len(points))))}


def write_vtu(path, qp, result) -> None:
    """Write displacement, von Mises stress and contact pressure to ``path`` (VTU)."""
    import meshio

    from workflows.io import atomic_path

    fields = contact_fields(qp, result)
    points, cells = fields["points"], fields["cells"]
    dim = points.shape[1]
    disp = fields["displacement"]
    if dim == 2:  # VTU wants 3D points and vectors
        points = np.hstack([points, np.zeros((len(points), 1))])
        disp = np.hstack([disp, np.zeros((len(disp), 1))])
    kind = "triangle" if cells.shape[1] == 3 else "tetra"
    mesh = meshio.Mesh(points, [(kind, cells)],
                       point_data={"displacement": disp, "contact_pressure": fields["contact_pressure"],
                                   "body": fields["body"].astype(float)},
                       cell_data={"von_mises": [fields["von_mises"]]})
    with atomic_path(path, suffix=".vtu") as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
