#!/usr/bin/env python3
"""Cut TOSCA pose sets to consistent disks: datasets/poses/<class>/.

For each class (wolf0-2, centaur0-2):
 1. Read all poses (ASCII OFF). They share the face list; the faces of pose 0
    are re-oriented consistently (BFS over faces, flipping each face to agree
    with its visited neighbour), then made outward (positive signed volume;
    checked on every pose). The same face list is used for every pose.
 2. Cut vertex s (pose 0): the surface vertex nearest to the area-weighted
    centroid of pose 0 (the middle of the torso, away from the extremities).
    Geodesic ball B = {v : d(s, v) < r} with d the Dijkstra edge-graph distance
    on pose 0 and r = 0.05 * sqrt(total area of pose 0). All faces touching B
    are removed. If the rest is not a disk (a boundary vertex touching two
    holes, or more than one component), offending boundary vertices are added
    to B and the step is repeated (the number of such repairs is reported).
 3. Unreferenced vertices are dropped with ONE index map per class (kept
    vertices in increasing original order), applied to every pose, so vertex i
    of wolf0.off corresponds to vertex i of wolf1.off. The map is written to
    original_indices.txt (line i = 0-based TOSCA index of new vertex i).
 4. Landmarks on pose 0 of the cut mesh (indices valid in every pose):
    extremities by farthest-point sampling of the geodesic distance, seeded
    with the boundary loop (first = farthest vertex from the cut, then the
    vertex farthest from the cut and all chosen ones, ...), K per class.
    They are named by geometry (feet: lowest z; front = side of the highest
    vertex along y; x sign for left/right; see datasets/README.md).
    center  = argmax over vertices of min(d(boundary, v), d(landmarks, v)):
              the vertex farthest from both the cut and the extremities.
    boundary = the boundary vertex of largest z on pose 0 (ties: lowest index).
Output: OFF with 6 significant digits.

Usage: python3 scripts/make_poses.py [--source ../shared/datasets]
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import meshtools as mt  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(REPO, "datasets", "poses")

# class -> (poses, number of extremity landmarks)
CLASSES = {
    "wolf": ([0, 1, 2], 6),       # 4 paws, nose, tail
    "centaur": ([0, 1, 2], 8),    # 4 hooves, 2 hands, head, tail
}
RADIUS_FACTOR = 0.05


def load_class(src, cls, poses):
    Vs, Fs, F0 = [], [], None
    for p in poses:
        V, F = mt.read_off(os.path.join(src, "tosca", "%s%d.off" % (cls, p)))
        if F0 is None:
            F0 = F
        else:
            # same edge set (winding may differ in some TOSCA files)
            if not np.array_equal(np.sort(F0, axis=1), np.sort(F, axis=1)):
                raise ValueError("%s%d: connectivity differs from pose 0" % (cls, p))
        Vs.append(V)
        Fs.append(F)
    return Vs, F0, Fs


def cut_disk(V, F, seed, r):
    """Remove the faces touching the geodesic ball of radius r around seed;
    repair until the remainder is a disk. Returns (kept faces mask, #repairs)."""
    adj = mt.vertex_adjacency(V, F)
    d = mt.dijkstra(V, F, [seed], adj)
    inball = d < r
    repairs = 0
    for _ in range(100):
        keep = ~inball[F].any(axis=1)
        Fk = F[keep]
        t = mt.topology(V, Fk)
        if t["class"] == "disk" and t["oriented"]:
            return keep, repairs, int(inball.sum())
        # boundary vertices whose boundary degree != 2 (touch the hole twice)
        he = mt.half_edges(Fk)
        dset = set(map(tuple, he.tolist()))
        deg = {}
        for a, b in he.tolist():
            if (b, a) not in dset:
                deg[a] = deg.get(a, 0) + 1
                deg[b] = deg.get(b, 0) + 1
        bad = [v for v, k in deg.items() if k != 2]
        if not bad:
            # bow-tie vertices or extra components: grow the ball by one ring
            ring = np.unique(F[inball[F].any(axis=1)])
            bad = ring.tolist()
        inball[bad] = True
        repairs += 1
    raise RuntimeError("could not cut a disk")


def name_landmarks(V, idx, height_frac=0.15):
    """Name extremity landmarks geometrically (pose 0 coordinates)."""
    z = V[:, 2]
    zmin, zmax = z.min(), z.max()
    top = int(np.argmax(z))
    ymid = 0.5 * (V[:, 1].min() + V[:, 1].max())
    front_sign = np.sign(V[top, 1] - ymid)  # the head is on the side of the highest point
    xspan = V[:, 0].max() - V[:, 0].min()
    names = {}
    rest = []
    for i in idx:
        p = V[i]
        if p[2] < zmin + height_frac * (zmax - zmin):
            fb = "front" if np.sign(p[1] - ymid) == front_sign else "hind"
            lr = "xpos" if p[0] > 0 else "xneg"
            names["foot_%s_%s" % (fb, lr)] = int(i)
        elif abs(p[0]) > 0.3 * xspan:
            names["hand_%s" % ("xpos" if p[0] > 0 else "xneg")] = int(i)
        else:
            rest.append(int(i))
    for i in rest:
        p = V[i]
        if np.sign(p[1] - ymid) == front_sign:
            key = "head"
        else:
            key = "tail"
        assert key not in names, (key, names)
        names[key] = i
    assert len(names) == len(idx), names
    return dict(sorted(names.items()))


def process(src, cls, poses, K, out):
    Vs, F, Fs_in = load_class(src, cls, poses)
    F, nflip = mt.orient_consistently(F)
    vols = [mt.signed_volume(V, F) for V in Vs]
    if vols[0] < 0:
        F = F[:, [0, 2, 1]]
        vols = [-v for v in vols]
    # faces whose upstream winding disagrees with the final (consistent, outward) one
    def cyc(G):
        k = np.argmin(G, axis=1)
        return np.stack([G[np.arange(len(G)), (k + j) % 3] for j in range(3)], axis=1)
    wrong = [int((cyc(G) != cyc(F)).any(axis=1).sum()) for G in Fs_in]
    assert all(v > 0 for v in vols), (cls, vols)
    t0 = mt.topology(Vs[0], F)
    assert t0["class"] == "sphere" and t0["oriented"], (cls, t0)
    V0 = Vs[0]
    A = mt.triangle_areas(V0, F)
    area = A.sum()
    centroid = (A[:, None] * V0[F].mean(axis=1)).sum(axis=0) / area
    seed = int(np.argmin(np.linalg.norm(V0 - centroid, axis=1)))
    r = RADIUS_FACTOR * np.sqrt(area)
    keep, repairs, nball = cut_disk(V0, F, seed, r)
    Fk = F[keep]
    used = np.unique(Fk)
    newidx = np.full(len(V0), -1, dtype=np.int64)
    newidx[used] = np.arange(len(used))
    Fn = newidx[Fk]
    os.makedirs(os.path.join(out, cls), exist_ok=True)
    rows = []
    for p, V in zip(poses, Vs):
        Vn = V[used]
        name = "%s%d.off" % (cls, p)
        path = os.path.join(out, cls, name)
        mt.write_off(path, Vn, Fn)
        Vr, Fr = mt.read_off(path)  # check what was written
        assert np.array_equal(Fr, Fn)
        t = mt.check_disk(Vr, Fr, name)
        rows.append((name, t["V"], t["F"], t["boundary_loops"], t["euler"], t["min_area"]))
    with open(os.path.join(out, cls, "original_indices.txt"), "w", newline="\n") as fh:
        fh.write("".join("%d\n" % i for i in used))
    # landmarks on pose 0 (cut mesh)
    Vc = V0[used]
    ext, center, boundary, center_to_boundary = mt.cut_markers(Vc, Fn, K)
    loop = mt.boundary_loops(Fn)[0]
    named = name_landmarks(Vc, ext)
    lm = {"center": center, "boundary": boundary, "landmarks": named}
    with open(os.path.join(out, cls, "landmarks.json"), "w") as fh:
        json.dump(lm, fh, indent=1)
    info = {
        "class": cls, "faces_flipped_by_reorientation": int(nflip),
        "upstream_faces_with_other_winding_per_pose": dict(zip(["%s%d" % (cls, p) for p in poses], wrong)), "signed_volumes": vols,
        "cut_seed_original_index": seed, "cut_seed_position_pose0": V0[seed].round(3).tolist(),
        "radius": float(r), "area_pose0": float(area), "ball_vertices": nball,
        "repairs": repairs, "faces_removed": int((~keep).sum()),
        "vertices_removed": int(len(V0) - len(used)),
        "boundary_loop_length": len(loop),
        "landmarks": lm,
        "landmark_positions_pose0": {k: Vc[v].round(2).tolist() for k, v in named.items()},
        "center_position_pose0": Vc[center].round(2).tolist(),
        "center_dist_to_boundary": center_to_boundary,
    }
    return rows, info


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", default=os.path.join(REPO, "..", "shared", "datasets"),
                    help="folder holding tosca/ (default ../shared/datasets relative to the repo)")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    allinfo = {}
    for cls, (poses, K) in CLASSES.items():
        rows, info = process(args.source, cls, poses, K, args.out)
        allinfo[cls] = info
        print(json.dumps(info, indent=1))
        for r in rows:
            print("%-16s V=%6d F=%6d loops=%d chi=%d min area=%.3e" % r)
        nv = {r[1] for r in rows}
        assert len(nv) == 1
    with open(os.path.join(args.out, "cut_info.json"), "w") as fh:
        json.dump(allinfo, fh, indent=1)


if __name__ == "__main__":
    main()
