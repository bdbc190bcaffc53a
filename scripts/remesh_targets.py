#!/usr/bin/env python3
"""Remeshed targets for `register-bench --remeshed`: every pose of a register-bench dataset
remeshed isotropically, so that a registration onto it shares no triangulation with its source.

For each class folder of DATASET (meshes sharing their vertex order, as `register-bench`
reads them) and each mesh CLASS/NAME.off, writes OUT/CLASS/NAME.off: pymeshlab's isotropic
explicit remeshing (`meshing_isotropic_explicit_remeshing`: target edge length `--scale` times
the mesh's mean edge length, `--iterations` rounds, surface distance checked against 0.2 times
that length, boundary kept as a feature), checked to be a disk (one component, one boundary
loop, manifold, oriented) without degenerate faces. A slit pose (`cut_pose_set.py --seam N`:
boundary vertices that coincide in space, the two sides of each slit) is welded along its slits
first, since the remeshing would weld them itself and the disk maps of the unslit remeshing
crowd beyond f64 (the lion poses); the remeshing is then slit again along the edge paths that
join the remeshed vertices nearest the slit's vertices, from its tip to the boundary. Nothing
else: `register-bench` carries the
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


def weld_slits(V, F):
    """(V, F) with the boundary vertices that coincide in space merged (the lowest index kept),
    unreferenced vertices dropped, and the slits as vertex paths of the welded mesh, each from its
    tip (a vertex on the slit that is no copy) to the boundary loop."""
    loop = mt.boundary_loops(F)[0]
    keep = np.arange(len(V))
    first = {}
    for v in sorted(int(x) for x in loop):
        key = tuple(V[v])
        if key in first:
            keep[v] = first[key]
        else:
            first[key] = v
    if np.all(keep == np.arange(len(V))):
        return V, F, []
    Fw = keep[F]
    used = np.unique(Fw)
    newidx = np.full(len(V), -1, dtype=np.int64)
    newidx[used] = np.arange(len(used))
    Fw, Vw = newidx[Fw], V[used]
    # the slit edges: boundary edges of (V, F) whose welded ends are an interior edge of (Vw, Fw)
    bw = set(int(x) for x in mt.boundary_loops(Fw)[0])
    loop = [int(x) for x in loop]
    edges = set()
    for a, b in zip(loop, loop[1:] + loop[:1]):
        a, b = int(newidx[keep[a]]), int(newidx[keep[b]])
        if a != b and not (a in bw and b in bw):
            edges.add((min(a, b), max(a, b)))
    nb = {}
    for a, b in edges:
        nb.setdefault(a, []).append(b)
        nb.setdefault(b, []).append(a)
    slits = []
    for tip in sorted(v for v, n in nb.items() if len(n) == 1 and v not in bw):
        path, prev = [tip], -1
        while path[-1] not in bw:
            nxt = [u for u in nb[path[-1]] if u != prev]
            prev = path[-1]
            path.append(nxt[0])
        slits.append(path)
    return Vw, Fw, slits


def reslit(V, F, Vw, slits):
    """Slits the remeshing (V, F) along the edge paths through its vertices nearest the welded
    slits' vertices (positions Vw), joined by shortest edge paths, loops removed. Returns the
    slit faces and, per vertex, the vertex it copies."""
    from cut_pose_set import cut_along

    adj = mt.vertex_adjacency(V, F)
    ptr, dst, ww = adj
    bnd = set(int(x) for x in mt.boundary_loops(F)[0])
    interior = np.array([v not in bnd for v in range(len(V))])
    edges = set()
    for slit in slits:
        stops = []
        for k, s in enumerate(slit):
            d = np.linalg.norm(V - Vw[s], axis=1)
            if k + 1 < len(slit):
                d[~interior] = np.inf
            else:
                d[interior] = np.inf
            w = int(np.argmin(d))
            if not stops or stops[-1] != w:
                stops.append(w)
        path = [stops[0]]
        for a, b in zip(stops, stops[1:]):
            d = mt.dijkstra(V, F, [b], adj)
            v = a
            while v != b:
                v = min((d[dst[k]] + ww[k], int(dst[k])) for k in range(ptr[v], ptr[v + 1]))[1]
                path.append(v)
        simple = []
        for v in path:
            if v in simple:
                del simple[simple.index(v) + 1:]
            else:
                simple.append(v)
        if any(v in bnd for v in simple[:-1]):
            raise SystemExit("remesh_targets: a slit's path on the remeshing touches the boundary before its end")
        for a, b in zip(simple, simple[1:]):
            edges.add((min(a, b), max(a, b)))
    return cut_along(F, len(V), edges)


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
            Vw, Fw, slits = weld_slits(V, F)
            V2, F2 = remesh(Vw, Fw, args.scale, args.iterations)
            if slits:
                F2, copies = reslit(V2, F2, Vw, slits)
                V2 = V2[copies]
            path = os.path.join(args.out, cls, os.path.splitext(f)[0] + ".off")
            tmp = path + ".tmp.off"
            mt.write_off(tmp, V2, F2, sig=9)
            Vr, Fr = mt.read_off(tmp)
            mt.check_disk(Vr, Fr, path)
            if not np.all(mt.triangle_areas(Vr, Fr) > 0):
                raise SystemExit("%s: the remeshing left a degenerate face" % path)
            os.replace(tmp, path)
            print(
                "%s: V %d -> %d, F %d -> %d%s"
                % (path, len(V), len(V2), len(F), len(F2), ", slit again along %d slits" % len(slits) if slits else ""),
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
