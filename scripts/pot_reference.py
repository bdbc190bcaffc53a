#!/usr/bin/env python3
"""Discrete OT reference for the semi-discrete solver (crates/omt/tests/solver_pot.rs).

Builds a source measure on the unit square whose mass is concentrated in K tiny equilateral
triangles (circumradius delta) around points s_k with masses a_k, plus a background density
of total mass `background` on the rest of the square (the solver needs a positive density on a
convex domain). The square is triangulated by Delaunay (scipy): each tiny triangle has an empty
circumcircle, so it is a Delaunay face. Targets: M points y_j with masses b_j (sum a = sum b = 1).

The exact discrete OT cost sum_kj P_kj |s_k - y_j|^2 is computed with POT's `ot.emd2`; the
semi-discrete cost from the tiny-triangle measure converges to it as delta -> 0 (error O(delta)
plus the background's share). Writes crates/omt/tests/fixtures/pot_discrete.json.

Usage: pip install pot numpy scipy; python3 scripts/pot_reference.py
Skips cleanly (exit 0) if POT, numpy or scipy is missing.
"""
import json
import os
import sys

try:
    import numpy as np
    import ot
    from scipy.spatial import Delaunay
except ImportError as e:  # pragma: no cover
    print(f"pot_reference.py: skipped ({e}); install with `pip install pot numpy scipy`")
    sys.exit(0)

DELTAS = [1e-2, 1e-3, 1e-4]
BACKGROUND = 1e-9  # total background mass (relative to the unit total)


def main():
    rng = np.random.default_rng(20261122)
    K, M = 6, 5
    sources = rng.uniform(0.15, 0.85, size=(K, 2))
    a = rng.uniform(0.5, 1.5, size=K)
    a /= a.sum()
    targets = rng.uniform(0.1, 0.9, size=(M, 2))
    b = rng.uniform(0.5, 1.5, size=M)
    b /= b.sum()
    cost_matrix = ot.dist(sources, targets, metric="sqeuclidean")
    discrete_cost = float(ot.emd2(a, b, cost_matrix))

    levels = []
    for delta in DELTAS:
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
        tiny = []
        for s in sources:
            for k in range(3):
                t = 2 * np.pi * k / 3 + np.pi / 2
                tiny.append(s + delta * np.array([np.cos(t), np.sin(t)]))
        vertices = np.vstack([corners, np.array(tiny)])
        tri = Delaunay(vertices)
        triangles = []
        densities = []
        tiny_faces = {tuple(sorted((4 + 3 * k, 5 + 3 * k, 6 + 3 * k))): k for k in range(K)}
        areas = []
        for simplex in tri.simplices:
            p = vertices[simplex]
            area2 = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[1, 1] - p[0, 1]) * (p[2, 0] - p[0, 0])
            if area2 < 0:
                simplex = simplex[[0, 2, 1]]
            triangles.append([int(v) for v in simplex])
            areas.append(abs(area2) / 2)
        found = [None] * K
        for f, t in enumerate(triangles):
            key = tuple(sorted(t))
            if key in tiny_faces:
                found[tiny_faces[key]] = f
        assert all(f is not None for f in found), "a tiny triangle is not a Delaunay face"
        background_area = 1.0 - sum(areas[f] for f in found)
        for f in range(len(triangles)):
            densities.append(BACKGROUND / background_area)
        for k, f in enumerate(found):
            densities[f] = a[k] / areas[f]
        levels.append({
            "delta": delta,
            "vertices": vertices.tolist(),
            "triangles": triangles,
            "densities": densities,
        })

    fixture = {
        "description": "K tiny triangles (masses a) vs M points (masses b) on the unit square; "
                       "discrete_cost = ot.emd2(a, b, |s_k - y_j|^2) (POT " + ot.__version__ + ")",
        "sources": sources.tolist(),
        "source_masses": a.tolist(),
        "targets": targets.tolist(),
        "target_masses": b.tolist(),
        "background_mass": BACKGROUND,
        "discrete_cost": discrete_cost,
        "levels": levels,
    }
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "crates", "omt", "tests", "fixtures", "pot_discrete.json")
    with open(out, "w") as fh:
        json.dump(fixture, fh, indent=1)
    print(f"discrete cost {discrete_cost:.12f}; wrote {os.path.normpath(out)}")


if __name__ == "__main__":
    main()
