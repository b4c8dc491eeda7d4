"""Local refinement libraries compared, for the adaptive loop of thesis Sect. 7.4.

Each candidate refines a mesh five times towards one point ``x0`` (every step
marks the cells whose centroid lies within ``3 h_T`` of ``x0``; the cells of
the closure come on top), and the script reports per candidate and mesh:

* wall time of the five refinement calls (median of ``--repeat`` runs,
  excluding mesh generation and the checks),
* nodes and cells after five steps,
* quality: smallest angle (2D) or smallest/largest dihedral angle (3D),
* conformity: every facet in at most two cells and the boundary measure
  unchanged (no hanging nodes; straight-sided domains only),
* nesting: old nodes keep their numbers and coordinates and every fine cell
  lies inside one coarse cell (barycentric test, tolerance 1e-9), each step.

Candidates: ``nvb`` and ``leb`` (:mod:`problems.fem.bisection`: newest-vertex
bisection, 2D; longest-edge bisection, 2D and 3D), ``skfem`` (scikit-fem 12's
``MeshTri.refined(marked)``: red-green-blue with the longest edge as reference
edge; ``MeshTet.refined(marked)``: longest-edge bisection), ``netgen``
(``ngsolve.Mesh.SetRefinementFlags`` + ``Refine``: netgen's bisection, on a
mesh netgen generated from an OCC geometry, since ``Refine`` on a mesh built
from arrays crashes; ``GetParentVertices`` gives the parents). Meshes: the
scenes' structured unit square (16 x 16) / cube (4^3) towards the contact
point, netgen's square / box of the same size for ``netgen``.

Usage::

    python workflows/scripts/bench_adaptive_refinement.py [--repeat 3] [--steps 5]
        [--square 16] [--cube 4]
"""
from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from problems.fem.bisection import (bisect, boundary_measure, facet_counts,  # noqa: E402
                                    label_longest_edge, min_angle)
from problems.fem.mesh import structured_cube, structured_square, tet_quality  # noqa: E402


DISK = (np.array([0.5, 1.707]), 0.707)          # the circle-square scene's circle
BALL = (np.array([0.5, 0.5, 1.866]), 0.866)     # the cube-sphere scene's ball


def marked_near(points, cells, x0, factor=3.0):
    """Cells whose centroid lies within ``factor * h_T`` of ``x0`` (h_T: longest edge)."""
    x = points[cells]
    n = cells.shape[1]
    h = np.max([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i in range(n)
                for j in range(i + 1, n)], axis=0)
    return np.linalg.norm(x.mean(axis=1) - x0, axis=1) <= factor * h


def inside_coarse(cp, cc, fp, fc, tol=1e-9):
    """Whether every fine cell lies in one coarse cell (its centroid's), by barycentrics."""
    cen = cp[cc].mean(axis=1)
    tree = cKDTree(cen)
    fcen = fp[fc].mean(axis=1)
    k = min(30, len(cc))
    _, cand = tree.query(fcen, k=k)
    X = cp[cc]                                      # (nc, d+1, d)
    T = np.transpose(X[:, 1:] - X[:, :1], (0, 2, 1))
    Tinv = np.linalg.inv(T)
    ok = np.zeros(len(fc), dtype=bool)
    for j in range(k):
        c = cand[:, j]
        pending = ~ok
        if not pending.any():
            break
        lam = np.einsum("fij,fvj->fvi", Tinv[c[pending]],
                        fp[fc[pending]] - X[c[pending], :1])          # (f, d+1, d)
        lam0 = 1.0 - lam.sum(axis=2)
        good = (lam >= -tol).all(axis=(1, 2)) & (lam0 >= -tol).all(axis=1)
        ok[np.flatnonzero(pending)[good]] = True
    return bool(ok.all())


def quality(points, cells):
    if points.shape[1] == 2:
        return {"min_angle": min_angle(points, cells)}
    q = tet_quality(points, cells)
    return {"min_dihedral": q["min_dihedral"], "max_dihedral": q["max_dihedral"]}


def run_ours(p, c, x0, steps, rule, project=None):
    if rule == "newest_vertex":
        c = label_longest_edge(p, c)
    meshes, t = [(p, c)], 0.0
    for _ in range(steps):
        m = marked_near(p, c, x0)
        t0 = time.perf_counter()
        ref = bisect(p, c, m, rule, project)
        t += time.perf_counter() - t0
        p, c = ref.points, ref.cells
        meshes.append((p, c))
    return meshes, t


def run_skfem(p, c, x0, steps, project=None):
    from skfem import MeshTet, MeshTri

    cls = MeshTri if p.shape[1] == 2 else MeshTet
    m = cls(np.ascontiguousarray(p.T), np.ascontiguousarray(c.T))
    meshes, t = [(p, c)], 0.0
    for _ in range(steps):
        marked = np.flatnonzero(marked_near(m.p.T, m.t.T, x0))
        n_old = m.p.shape[1]
        t0 = time.perf_counter()
        m = m.refined(marked)
        t += time.perf_counter() - t0
        if project is not None:                       # new boundary nodes onto the curve
            bnd = np.zeros(m.p.shape[1], dtype=bool)
            bnd[m.boundary_nodes()] = True
            bnd[:n_old] = False
            m = cls(np.ascontiguousarray(project(m.p.T, bnd).T), m.t)
        meshes.append((m.p.T.copy(), m.t.T.copy()))
    return meshes, t


def _ng_arrays(mesh, dim):
    ng = mesh.ngmesh
    pts = np.array(ng.Coordinates())[:, :dim]
    els = ng.Elements2D() if dim == 2 else ng.Elements3D()
    cells = np.array([[v.nr - 1 for v in el.vertices] for el in els], dtype=np.int64)
    return pts, cells


def run_netgen(dim, x0, steps, h, curved=False):
    import ngsolve
    from netgen.occ import Box, Circle, MoveTo, OCCGeometry, Pnt, Sphere

    if dim == 2:
        geo = OCCGeometry((Circle(tuple(map(float, DISK[0])), DISK[1]).Face() if curved
                           else MoveTo(0, 0).Rectangle(1, 1).Face()), dim=2)
    else:
        geo = OCCGeometry(Sphere(Pnt(*map(float, BALL[0])), BALL[1]) if curved
                          else Box(Pnt(0, 0, 0), Pnt(1, 1, 1)))
    mesh = ngsolve.Mesh(geo.GenerateMesh(maxh=h))
    p, c = _ng_arrays(mesh, dim)
    meshes, t, parents_ok = [(p, c)], 0.0, True
    for _ in range(steps):
        flags = marked_near(p, c, x0)
        n_old = len(p)
        t0 = time.perf_counter()
        mesh.SetRefinementFlags([bool(f) for f in flags])
        mesh.Refine()
        t += time.perf_counter() - t0
        p, c = _ng_arrays(mesh, dim)
        par = np.array([mesh.GetParentVertices(v) for v in range(n_old, len(p))])
        if not curved:
            parents_ok &= bool(np.allclose(p[n_old:], 0.5 * (p[par[:, 0]] + p[par[:, 1]]),
                                           atol=1e-12))
        meshes.append((p, c))
    return meshes, t, parents_ok


def check_curved(meshes, center, radius):
    """Conformity on a disk/ball: facets in at most two cells and every boundary node on the
    circle/sphere (a hanging node would leave boundary facets inside)."""
    from problems.fem.elasticity import boundary_facets

    conf = all(facet_counts(c).max() <= 2 for _, c in meshes)
    for p, c in meshes:
        b = np.unique(boundary_facets(c))
        conf &= bool(np.allclose(np.linalg.norm(p[b] - center, axis=1), radius, rtol=1e-6))
    return conf


def check(meshes):
    conf = all(facet_counts(c).max() <= 2 for _, c in meshes)
    bm0 = boundary_measure(*meshes[0])
    conf &= all(abs(boundary_measure(p, c) - bm0) < 1e-9 * bm0 for p, c in meshes)
    nested = True
    for (cp, cc), (fp, fc) in zip(meshes[:-1], meshes[1:]):
        nested &= bool(np.array_equal(fp[:len(cp)], cp)) and inside_coarse(cp, cc, fp, fc)
    return conf, nested


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--square", type=int, default=16, help="cells per edge of the square")
    ap.add_argument("--cube", type=int, default=4, help="cells per edge of the cube")
    args = ap.parse_args(argv)
    rows = []
    from problems.fem.mesh import netgen_ball, netgen_disk, project_to_circle

    for dim in (2, 3):
        center, radius = (DISK if dim == 2 else BALL)
        x0 = center - np.eye(dim)[-1] * radius           # the lowest point: the contact point
        proj = project_to_circle(center, radius)
        p, c = (netgen_disk(center, radius, 0.05) if dim == 2
                else netgen_ball(center, radius, 0.21, 0.3))
        cands = {"leb": lambda: run_ours(p, c, x0, args.steps, "longest_edge", proj),
                 "skfem": lambda: run_skfem(p, c, x0, args.steps, proj),
                 "netgen": lambda: run_netgen(dim, x0, args.steps, 0.05 if dim == 2 else 0.21,
                                              curved=True)}
        if dim == 2:
            cands = {"nvb": lambda: run_ours(p, c, x0, args.steps, "newest_vertex", proj),
                     **cands}
        for name, fn in cands.items():
            times = []
            for _ in range(args.repeat):
                out = fn()
                times.append(out[1])
            meshes = out[0]
            fp, fc = meshes[-1]
            rows.append({"dim": dim, "mesh": "disk" if dim == 2 else "ball", "candidate": name,
                         "time_s": float(np.median(times)), "nodes0": len(meshes[0][0]),
                         "nodes": len(fp), "cells": len(fc), **quality(fp, fc),
                         "min_q0": list(quality(*meshes[0]).values())[0],
                         "conforming": check_curved(meshes, center, radius), "nested": ""})
    for dim in (2, 3):
        x0 = np.array([0.5, 1.0]) if dim == 2 else np.array([0.5, 0.5, 1.0])
        n = args.square if dim == 2 else args.cube
        p, c = structured_square(n) if dim == 2 else structured_cube(n)
        cands = {"leb": lambda: run_ours(p, c, x0, args.steps, "longest_edge"),
                 "skfem": lambda: run_skfem(p, c, x0, args.steps),
                 "netgen": lambda: run_netgen(dim, x0, args.steps, 1 / n)}
        if dim == 2:
            cands = {"nvb": lambda: run_ours(p, c, x0, args.steps, "newest_vertex"), **cands}
        for name, fn in cands.items():
            times = []
            for _ in range(args.repeat):
                out = fn()
                times.append(out[1])
            meshes = out[0]
            conf, nested = check(meshes)
            if name == "netgen":
                nested &= out[2]
            fp, fc = meshes[-1]
            rows.append({"dim": dim, "mesh": "square" if dim == 2 else "cube",
                         "candidate": name, "time_s": float(np.median(times)),
                         "nodes0": len(meshes[0][0]), "nodes": len(fp), "cells": len(fc),
                         **quality(fp, fc), "min_q0": list(quality(*meshes[0]).values())[0],
                         "conforming": conf, "nested": nested})
    keys = list(dict.fromkeys(k for r in rows for k in r))
    print(",".join(keys))
    for r in rows:
        print(",".join(f"{r[k]:.4g}" if isinstance(r.get(k), float) else str(r.get(k, ""))
                       for k in keys))


if __name__ == "__main__":
    main()
