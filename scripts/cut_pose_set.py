#!/usr/bin/env python3
"""Cut a closed genus-0 pose set (one connectivity) to disks for `register-bench`.

The rules of make_poses.py, for any set of poses that share their face list (lion poses,
Sumner & Popovic's cat poses): faces oriented consistently and outward on pose 0, a geodesic
ball of radius 0.05 sqrt(area) (`--radius`) removed around the vertex nearest the area centroid of pose 0
(grown until the rest is a disk), unreferenced vertices dropped with one index map, OFF with
6 significant digits. Landmarks are K extremities by farthest-point sampling from the cut
(named x0, x1, ... in the order found; the same indices in every pose), `center` the vertex
farthest from the cut and the extremities, `boundary` the boundary vertex of largest z.

`--seam N` then slits the disk of pose 0 from its N farthest tips (farthest-point sampling from
the boundary, edge-path distances, as `shapespace prepare --seam N`) along shortest edge paths
to the boundary or to the slits made so far; every pose is cut along the same edges, so the
poses keep one vertex order (a slit vertex's extra copies are appended after the others). The
landmarks are chosen after the slit. Poses whose limbs the disk cut alone crowds beyond f64 in
the conformal map (the lion poses) map with one slit.

`--fill-holes` first closes small holes (the Sumner horse poses have a 16-vertex and a
3-vertex loop): a loop of three vertices by one triangle, a longer one by a fan around a new
vertex at the loop's centroid (per pose), so that the set is closed genus 0 before the cut.

The output is derived from public research data: write it outside the repository.

Usage: python3 scripts/cut_pose_set.py --out DIR/CLASS [--landmarks 6] [--radius 0.05] [--fill-holes] [--seam N] POSE0 POSE1 ...
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import meshtools as mt  # noqa: E402
from make_poses import RADIUS_FACTOR, cut_disk  # noqa: E402


def fill_holes(Vs, F):
    """Closes every boundary loop of the shared connectivity F (oriented consistently): one
    triangle for a loop of three, else a fan around a new vertex at the loop's centroid in each
    pose. Returns the new poses and faces."""
    loops = mt.boundary_loops(F)
    faces, extra = [F], [[] for _ in Vs]
    n = len(Vs[0])
    for loop in loops:
        # a boundary half-edge a -> b has its face on the left: the cap runs b -> a
        if len(loop) == 3:
            faces.append(np.array([[loop[2], loop[1], loop[0]]]))
            continue
        c = n + len(extra[0])
        for k, V in enumerate(Vs):
            extra[k].append(V[loop].mean(axis=0))
        faces.append(np.array([[loop[(i + 1) % len(loop)], loop[i], c] for i in range(len(loop))]))
    Vs = [np.vstack([V] + ([np.array(e)] if e else [])) for V, e in zip(Vs, extra)]
    return Vs, np.vstack(faces), len(loops)


def seam_edges(V, F, count):
    """The edges of `count` slits of the disk (V, F): each joins the vertex farthest (edge-path
    distance) from the boundary and the slits so far to the nearest of them by a shortest edge
    path. Returns a set of (min, max) vertex pairs."""
    adj = mt.vertex_adjacency(V, F)
    ptr, dst, ww = adj
    tree = list(mt.boundary_loops(F)[0])
    edges = set()
    for _ in range(count):
        d = mt.dijkstra(V, F, tree, adj)
        tip = int(np.argmax(d))
        path = [tip]
        on_tree = np.zeros(len(V), dtype=bool)
        on_tree[tree] = True
        v = tip
        while not on_tree[v]:
            # step to the neighbour on a shortest path back to the tree
            nb = [(d[dst[k]] + ww[k], int(dst[k])) for k in range(ptr[v], ptr[v + 1])]
            v = min(nb)[1]
            path.append(v)
        for a, b in zip(path, path[1:]):
            edges.add((min(a, b), max(a, b)))
        tree.extend(path)
    return edges


def cut_along(F, n, cut):
    """Cuts the faces F (n vertices) open along the edge set `cut`: the corners of a vertex are
    joined across its uncut edges, each class of corners becomes one vertex (the class holding the
    vertex's first face keeps its index, the others are appended). Returns the new faces and, per
    new vertex, the old vertex it copies."""
    F = np.asarray(F)
    parent = list(range(3 * len(F)))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    owner = {}
    for f, tri in enumerate(F):
        for i in range(3):
            a, b = int(tri[i]), int(tri[(i + 1) % 3])
            key = (min(a, b), max(a, b))
            if key in cut:
                continue
            if key in owner:
                g, _ = owner.pop(key)
                # corner of a in f with corner of a in g, likewise b
                ga = [k for k in range(3) if F[g][k] == a][0]
                gb = [k for k in range(3) if F[g][k] == b][0]
                for c1, c2 in ((3 * f + i, 3 * g + ga), (3 * f + (i + 1) % 3, 3 * g + gb)):
                    r1, r2 = find(c1), find(c2)
                    if r1 != r2:
                        parent[max(r1, r2)] = min(r1, r2)
            else:
                owner[key] = (f, i)
    new_index = {find(c): None for c in range(3 * len(F))}
    copies = list(range(n))
    Fn = np.empty_like(F)
    # the class of the smallest corner of each vertex keeps the index
    first = {}
    for r in sorted(new_index):
        v = int(F[r // 3][r % 3])
        if v not in first:
            first[v] = r
            new_index[r] = v
        else:
            new_index[r] = len(copies)
            copies.append(v)
    for f in range(len(F)):
        for i in range(3):
            Fn[f, i] = new_index[find(3 * f + i)]
    return Fn, np.array(copies, dtype=np.int64)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="class folder to write (created)")
    ap.add_argument("--landmarks", type=int, default=6)
    ap.add_argument("--radius", type=float, default=RADIUS_FACTOR, help="cut radius over sqrt(area)")
    ap.add_argument("--fill-holes", action="store_true", help="close boundary loops first (see above)")
    ap.add_argument("--seam", type=int, default=0, help="slits from the N farthest tips (see above)")
    ap.add_argument("poses", nargs="+")
    args = ap.parse_args()
    Vs, F0 = [], None
    for p in args.poses:
        V, F = mt.read_mesh(p)
        if F0 is None:
            F0 = F
        elif not np.array_equal(np.sort(F0, axis=1), np.sort(F, axis=1)):
            raise SystemExit("%s: connectivity differs from %s" % (p, args.poses[0]))
        Vs.append(V)
    F, _ = mt.orient_consistently(F0)
    if args.fill_holes:
        Vs, F, filled = fill_holes(Vs, F)
        print("filled %d holes" % filled)
    if mt.signed_volume(Vs[0], F) < 0:
        F = F[:, [0, 2, 1]]
    t0 = mt.topology(Vs[0], F)
    if t0["class"] != "sphere":
        raise SystemExit("pose 0 is not a closed genus-0 surface: %s" % t0)
    V0 = Vs[0]
    A = mt.triangle_areas(V0, F)
    area = A.sum()
    centroid = (A[:, None] * V0[F].mean(axis=1)).sum(axis=0) / area
    seed = int(np.argmin(np.linalg.norm(V0 - centroid, axis=1)))
    keep, repairs, _ = cut_disk(V0, F, seed, args.radius * np.sqrt(area))
    Fk = F[keep]
    used = np.unique(Fk)
    newidx = np.full(len(V0), -1, dtype=np.int64)
    newidx[used] = np.arange(len(used))
    Fn = newidx[Fk]
    Vs = [V[used] for V in Vs]
    if args.seam > 0:
        Fn, copies = cut_along(Fn, len(used), seam_edges(Vs[0], Fn, args.seam))
        Vs = [V[copies] for V in Vs]
        print("slit along %d tips: %d vertices added" % (args.seam, len(copies) - len(used)))
    os.makedirs(args.out, exist_ok=True)
    cls = os.path.basename(os.path.normpath(args.out))
    for i, V in enumerate(Vs):
        path = os.path.join(args.out, "%s%d.off" % (cls, i))
        mt.write_off(path, V, Fn)
        Vr, Fr = mt.read_off(path)
        mt.check_disk(Vr, Fr, path)
    Vc = Vs[0]
    ext, center, boundary, _ = mt.cut_markers(Vc, Fn, args.landmarks)
    lm = {"center": center, "boundary": boundary, "landmarks": {"x%d" % i: int(v) for i, v in enumerate(ext)}}
    with open(os.path.join(args.out, "landmarks.json"), "w") as fh:
        json.dump(lm, fh, indent=1)
    print("%s: %d poses, V=%d F=%d, %d repairs of the cut, landmarks %s" % (
        cls, len(Vs), len(Vs[0]), len(Fn), repairs, lm))


if __name__ == "__main__":
    main()
