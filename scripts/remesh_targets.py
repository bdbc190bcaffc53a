#!/usr/bin/env python3
"""Remeshed targets for `register-bench --remeshed`: every pose of a register-bench dataset
remeshed isotropically, so that a registration onto it shares no triangulation with its source.

For each class folder of DATASET (meshes sharing their vertex order, as `register-bench`
reads them) and each mesh CLASS/NAME.off, writes OUT/CLASS/NAME.off: pymeshlab's isotropic
explicit remeshing (`meshing_isotropic_explicit_remeshing`: target edge length `--scale` times
the mesh's mean edge length, `--iterations` rounds, surface distance checked against 0.2 times
that length, boundary kept as a feature), checked to be a disk (one component, one boundary
loop, manifold, oriented) without degenerate faces. Nothing else: `register-bench` carries the
ground truth (closest points) and the markers (nearest vertices) over itself.

pymeshlab is not a dependency of the repository: install it into a virtual environment outside
it (`python3 -m venv VENV && VENV/bin/pip install pymeshlab`). Without it the script prints a
message and exits with status 0. The output is derived from the input meshes: when those are
public research data, write it outside the repository.

Usage: python3 scripts/remesh_targets.py DATASET --out OUT [--scale 1.0] [--iterations 6]
"""

import argparse
import os
import sys

try:
    import numpy as np

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import meshtools as mt
except ImportError:
    print("remesh_targets: NumPy is not installed; skipped")
    sys.exit(0)


def remesh(V, F, scale, iterations):
    """Isotropic remeshing of (V, F) at `scale` times the mean edge length."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int32)))
    edge = np.linalg.norm(V[F[:, [1, 2, 0]]] - V[F], axis=2).mean()
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations,
        targetlen=pymeshlab.PureValue(scale * edge),
        featuredeg=180,
        checksurfdist=True,
        maxsurfdist=pymeshlab.PureValue(0.2 * scale * edge),
    )
    ms.meshing_remove_unreferenced_vertices()
    m = ms.current_mesh()
    return m.vertex_matrix().copy(), m.face_matrix().astype(np.int64)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", help="folder of class folders (as register-bench reads)")
    ap.add_argument("--out", required=True, help="folder to write OUT/CLASS/NAME.off into (created)")
    ap.add_argument("--scale", type=float, default=1.0, help="target edge length over the mean edge length")
    ap.add_argument("--iterations", type=int, default=6)
    args = ap.parse_args()
    try:
        import pymeshlab  # noqa: F401
    except ImportError:
        print("remesh_targets: pymeshlab is not installed (pip install pymeshlab in a virtual environment); skipped")
        return 0
    if os.path.realpath(args.out) == os.path.realpath(args.dataset):
        raise SystemExit("remesh_targets: --out must differ from DATASET (the inputs are not overwritten)")
    classes = sorted(d for d in os.listdir(args.dataset) if os.path.isdir(os.path.join(args.dataset, d)))
    for cls in classes:
        folder = os.path.join(args.dataset, cls)
        files = sorted(f for f in os.listdir(folder) if f.lower().endswith((".off", ".obj", ".ply")))
        if len(files) < 2:
            continue
        os.makedirs(os.path.join(args.out, cls), exist_ok=True)
        for f in files:
            V, F = mt.read_mesh(os.path.join(folder, f))
            V2, F2 = remesh(V, F, args.scale, args.iterations)
            path = os.path.join(args.out, cls, os.path.splitext(f)[0] + ".off")
            tmp = path + ".tmp.off"
            mt.write_off(tmp, V2, F2, sig=9)
            Vr, Fr = mt.read_off(tmp)
            mt.check_disk(Vr, Fr, path)
            if not np.all(mt.triangle_areas(Vr, Fr) > 0):
                raise SystemExit("%s: the remeshing left a degenerate face" % path)
            os.replace(tmp, path)
            print("%s: V %d -> %d, F %d -> %d" % (path, len(V), len(V2), len(F), len(F2)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
