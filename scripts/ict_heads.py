#!/usr/bin/env python3
"""Closed genus-0 heads from the ICT FaceKit model: identities x expressions.

Each head is the model's face + head & neck region (11,248 vertices, 22,288 triangles,
../shared/datasets/ict_facekit, see its SOURCE.md)
    V = N + sum_{k<40} a_k identity_delta_k + sum_j w_j expression_delta_j
with its four boundary loops (neck, both eye openings, mouth) closed by centroid fans
(L[j+1], L[j], c), c at the mean of the loop's vertices: 11,252 vertices, 22,500 triangles,
closed, χ = 2. Identity i uses a_k = random.Random(i).gauss(0, 1) (the upstream sampler's
N(0, 1) scale; Python's generator, as numpy is not needed). Expressions, by weight:
    0: neutral; 1: jawOpen 0.6; 2: mouthSmile_L, mouthSmile_R 1.0, eyeBlink_L, eyeBlink_R 0.5;
    3: browInnerUp_L, browInnerUp_R 1.0, mouthPucker 0.8.
Writes OUT/head<I>_<E>.obj for each identity I and expression E given, so that
`scripts/sphere_disk_ranking.py` takes each identity as one class (the name without its
trailing digits). The heads are derived from public research data: write them outside the
repository.

Usage: python3 scripts/ict_heads.py OUT [--source ../shared/datasets] [--identities 1,2]
       [--expressions 0,1,2]
"""

import argparse
import array
import ast
import heapq
import json
import math
import os
import random
import sys

EXPRESSIONS = [
    {},
    {"jawOpen": 0.6},
    {"mouthSmile_L": 1.0, "mouthSmile_R": 1.0, "eyeBlink_L": 0.5, "eyeBlink_R": 0.5},
    {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0, "mouthPucker": 0.8},
]
IDENTITY_MODES = 40


def read_npy(path):
    """(typecode data, shape) of a little-endian C-order NumPy v1.0 file of <f4, <f8 or <i4."""
    with open(path, "rb") as f:
        magic = f.read(8)
        if magic[:6] != b"\x93NUMPY":
            sys.exit(f"{path}: not a NumPy file")
        header_len = int.from_bytes(f.read(2), "little")
        header = ast.literal_eval(f.read(header_len).decode("latin1"))
        if header["fortran_order"]:
            sys.exit(f"{path}: Fortran order is not read")
        code = {"<f4": "f", "<f8": "d", "<i4": "i"}[header["descr"]]
        data = array.array(code)
        data.frombytes(f.read())
        if sys.byteorder != "little":
            data.byteswap()
    return data, header["shape"]


def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def normal(p, f):
    u, v = sub(p[f[1]], p[f[0]]), sub(p[f[2]], p[f[0]])
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def decimate(pos, faces, target):
    """Faces of a closed manifold mesh after half-edge collapses (u removed, v kept where it is),
    shortest edge first, down to `target` vertices: a collapse keeps the link condition (u and v
    share exactly the two vertices opposite their edge) and turns no face's normal by more than
    60 degrees. Returns the kept vertices (sorted) and the faces in their new numbering."""
    alive = [True] * len(faces)
    vfaces = [set() for _ in pos]
    for i, f in enumerate(faces):
        for v in f:
            vfaces[v].add(i)

    def ring(v):
        return {w for i in vfaces[v] for w in faces[i]} - {v}

    heap = []
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            if a < b:
                heap.append((math.dist(pos[a], pos[b]), a, b))
    heapq.heapify(heap)
    removed = set()
    count = len(pos)
    while heap and count > target:
        _, a, b = heapq.heappop(heap)
        if a in removed or b in removed or b not in ring(a):
            continue
        for u, v in ((a, b), (b, a)):
            if len(ring(u) & ring(v)) != 2:
                break
            moved = [i for i in vfaces[u] if v not in faces[i]]
            ok = True
            for i in moved:
                n0 = normal(pos, faces[i])
                n1 = normal(pos, [v if w == u else w for w in faces[i]])
                l0, l1 = math.hypot(*n0), math.hypot(*n1)
                if l1 == 0.0 or sum(x * y for x, y in zip(n0, n1)) < 0.5 * l0 * l1:
                    ok = False
                    break
            if not ok:
                continue
            for i in list(vfaces[u]):
                if v in faces[i]:
                    alive[i] = False
                    for w in faces[i]:
                        vfaces[w].discard(i)
            for i in moved:
                faces[i] = [v if w == u else w for w in faces[i]]
                vfaces[v].add(i)
            vfaces[u] = set()
            removed.add(u)
            count -= 1
            for w in ring(v):
                heapq.heappush(heap, (math.dist(pos[v], pos[w]), min(v, w), max(v, w)))
            break
    kept = [v for v in range(len(pos)) if v not in removed]
    index = {v: k for k, v in enumerate(kept)}
    return kept, [[index[w] for w in f] for i, f in enumerate(faces) if alive[i]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--source", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared", "datasets"))
    ap.add_argument("--identities", default="1,2")
    ap.add_argument("--expressions", default="0,1,2")
    ap.add_argument("--vertices", type=int, help="decimate to about this many vertices (one connectivity for all heads)")
    args = ap.parse_args()
    src = os.path.join(args.source, "ict_facekit")
    if not os.path.isdir(src):
        print(f"SKIPPED: {src} not found")
        return
    neutral, (nv, _) = read_npy(os.path.join(src, "neutral_vertices_f64.npy"))
    tris, (nf, _) = read_npy(os.path.join(src, "face_and_head_triangles.npy"))
    ident, id_shape = read_npy(os.path.join(src, "identity_deltas.npy"))
    expr, _ = read_npy(os.path.join(src, "expression_deltas.npy"))
    names = json.load(open(os.path.join(src, "names.json")))["expressions"]
    loops = json.load(open(os.path.join(src, "face_region_boundary_loops.json")))["face_and_head"]
    loops = [loops[k]["vertices"] for k in ("outer", "eye_xpos", "eye_xneg", "mouth")]
    stride = nv * 3
    faces = [list(tris[3 * f : 3 * f + 3]) for f in range(nf)]
    verts = [neutral[3 * v : 3 * v + 3] for v in range(nv)]
    for loop in loops:
        c = len(verts)
        verts.append([sum(verts[v][d] for v in loop) / len(loop) for d in range(3)])
        faces += [[loop[(j + 1) % len(loop)], loop[j], c] for j in range(len(loop))]
    kept, faces = (list(range(len(verts))), faces) if args.vertices is None else decimate(verts, faces, args.vertices)
    os.makedirs(args.out, exist_ok=True)
    for i in [int(s) for s in args.identities.split(",")]:
        rng = random.Random(i)
        coeffs = [rng.gauss(0.0, 1.0) for _ in range(min(IDENTITY_MODES, id_shape[0]))]
        base = list(neutral)
        for k, a in enumerate(coeffs):
            off = k * stride
            for t in range(stride):
                base[t] += a * ident[off + t]
        for e in [int(s) for s in args.expressions.split(",")]:
            pos = list(base)
            for name, w in EXPRESSIONS[e].items():
                off = names.index(name) * stride
                for t in range(stride):
                    pos[t] += w * expr[off + t]
            verts = [pos[3 * v : 3 * v + 3] for v in range(nv)]
            for loop in loops:
                verts.append([sum(verts[v][d] for v in loop) / len(loop) for d in range(3)])
            verts = [verts[v] for v in kept]
            path = os.path.join(args.out, f"head{i}_{e}.obj")
            with open(path, "w") as f:
                f.write(f"# ICT FaceKit head, identity {i} (40 modes, random.Random({i}).gauss), expression {e}\n")
                f.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in verts)
                f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
            print(f"{path}: {len(verts)} V, {len(faces)} F")


if __name__ == "__main__":
    main()
