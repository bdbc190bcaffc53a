#!/usr/bin/env python3
"""Runs the ot_bench uniform-disk cases (N uniform random points in the unit disk, equal masses,
uniform density on the unit disk) with pysdot's damped Newton solver, for comparison with
`cargo bench -p shapespace-omt --bench ot_bench`. The random points differ from the Rust bench's
(different generators) but have the same distribution.

Usage: python3 scripts/bench_pysdot.py [N ...]   (default 1000 10000 100000)
Prints a skip message and exits 0 if pysdot (or numpy) is not importable.
"""
import sys
import time

try:
    import numpy as np
    from pysdot import OptimalTransport
    from pysdot.domain_types import ConvexPolyhedraAssembly
except ImportError as e:  # pragma: no cover
    print(f"bench_pysdot.py: skipped ({e}); install with `pip install pysdot numpy`")
    sys.exit(0)


def disk_domain(vertices=512):
    domain = ConvexPolyhedraAssembly()
    t = np.linspace(0, 2 * np.pi, vertices, endpoint=False)
    polygon = np.stack([np.cos(t), np.sin(t)], axis=1)
    # One row per edge: a point on it (vertex k) and the outward normal (angle t_k + pi/n).
    normals = t + np.pi / vertices
    domain.add_convex_polyhedron([[p[0], p[1], np.cos(a), np.sin(a)] for p, a in zip(polygon, normals)])
    return domain


def main():
    sizes = [int(float(a)) for a in sys.argv[1:]] or [1000, 10000, 100000]
    rng = np.random.default_rng(2024)
    print("| N | steps | total/s | max rel. mass error |")
    print("|---:|---:|---:|---:|")
    for n in sizes:
        r = np.sqrt(rng.uniform(size=n))
        t = 2 * np.pi * rng.uniform(size=n)
        points = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
        domain = disk_domain()
        masses = np.full(n, domain.measure() / n)
        # the same stop as ot_bench's: every cell within a relative mass error of 1e-6 (pysdot's
        # default stops on the weights' change instead, one Newton step later)
        ot = OptimalTransport(points, domain=domain, obj_max_dw=0, obj_max_dm=1e-6 * masses[0])
        ot.set_masses(masses)
        start = time.perf_counter()
        ot.adjust_weights()
        elapsed = time.perf_counter() - start
        cell_masses = ot.pd.integrals()
        error = np.max(np.abs(cell_masses - masses) / masses)
        steps = getattr(ot, "nb_iter", "?")
        print(f"| {n} | {steps} | {elapsed:.2f} | {error:.2e} |")


if __name__ == "__main__":
    main()
