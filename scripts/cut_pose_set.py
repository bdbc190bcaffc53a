#!/usr/bin/env python3
"""Cut a closed genus-0 pose set (one connectivity) to disks for `register-bench`.

The rules of make_poses.py, for any set of poses that share their face list (lion poses,
Sumner & Popovic's cat poses): faces oriented consistently and outward on pose 0, a geodesic
ball of radius 0.05 sqrt(area) (`--radius`) removed around the vertex nearest the area centroid of pose 0
(grown until the rest is a disk), unreferenced vertices dropped with one index map, OFF with
6 significant digits. Landmarks are K extremities by farthest-point sampling from the cut
(named x0, x1, ... in the order found; the same indices in every pose), `center` the vertex
farthest from the cut and the extremities, `boundary` the boundary vertex of largest z.

`--fill-holes` first closes small holes (the Sumner horse poses have a 16-vertex and a
3-vertex loop): a loop of three vertices by one triangle, a longer one by a fan around a new
vertex at the loop's centroid (per pose), so that the set is closed genus 0 before the cut.

The output is derived from public research data: write it outside the repository.

Usage: python3 scripts/cut_pose_set.py --out DIR/CLASS [--landmarks 6] [--radius 0.05] [--fill-holes] POSE0 POSE1 ...
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


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="class folder to write (created)")
    ap.add_argument("--landmarks", type=int, default=6)
    ap.add_argument("--radius", type=float, default=RADIUS_FACTOR, help="cut radius over sqrt(area)")
    ap.add_argument("--fill-holes", action="store_true", help="close boundary loops first (see above)")
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
    os.makedirs(args.out, exist_ok=True)
    cls = os.path.basename(os.path.normpath(args.out))
    for i, V in enumerate(Vs):
        path = os.path.join(args.out, "%s%d.off" % (cls, i))
        mt.write_off(path, V[used], Fn)
        Vr, Fr = mt.read_off(path)
        mt.check_disk(Vr, Fr, path)
    Vc = V0[used]
    ext, center, boundary, _ = mt.cut_markers(Vc, Fn, args.landmarks)
    lm = {"center": center, "boundary": boundary, "landmarks": {"x%d" % i: int(v) for i, v in enumerate(ext)}}
    with open(os.path.join(args.out, "landmarks.json"), "w") as fh:
        json.dump(lm, fh, indent=1)
    print("%s: %d poses, V=%d F=%d, %d repairs of the cut, landmarks %s" % (
        cls, len(Vs), len(used), len(Fn), repairs, lm))


if __name__ == "__main__":
    main()
