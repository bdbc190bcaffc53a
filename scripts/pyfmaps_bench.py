#!/usr/bin/env python3
"""Functional-map peer for `register-bench`: pyfmaps (pyFM) + ZoomOut on the same pose pairs,
scored by register-bench's geodesic error.

For every class folder of DATASET (the layout `register-bench` reads: meshes sharing their
vertex order and a `landmarks.json`) and every ordered pair (source, target), the vertex map
source -> target is computed with pyFM as in its README quick start (WKS descriptors with the
named landmarks added as landmark descriptors, K = 30, w_descr = 1, w_lap = 0.1, w_dcomm = 1,
w_orient = 1, then ZoomOut with 16 iterations of step 5), and scored like `register-bench`:
for 300 source vertices v sampled by shapespace's `sample_indices` (splitmix64, seed 7), the
heat-method geodesic distance on the target between the image of v and its true partner,
divided by sqrt(area of the target). The heat method is reimplemented here exactly as in
crates/analysis/src/registration/geodesic.rs (t = mean edge length squared, lumped masses, Neumann, the
Poisson solve pinned at vertex 0).

With `--remeshed DIR --truth DIR` (what `register-bench --remeshed` reads and writes) each
source is also mapped onto the remeshings of the other poses, DIR/CLASS/NAME.off, with the
markers and the ground truth register-bench carried over (TRUTH/CLASS/NAME.landmarks.json, and
TRUTH/CLASS/NAME.csv: per vertex of the pose, the closest point of the remeshing as face and
barycentric coordinates, a heat source spread over the face's corners as in
`HeatGeodesics::distances_from_points`). The CSV's `triangulation` column says which.

`--check OUT SOURCE TARGET` instead reads a `shapespace register --out OUT` result
(`correspondence.csv`, `metrics.json`) and compares this script's error of shapespace's own map
with the per-sample errors in `metrics.json` (the cross-check of the error definition).

pyfmaps is not a dependency of the repository: install it into a virtual environment outside
it (`python3 -m venv VENV && VENV/bin/pip install pyfmaps`). Without it the script prints a
message and exits with status 0 (nothing measured); `--check` needs only NumPy and SciPy.

Usage:
  python3 scripts/pyfmaps_bench.py DATASET --out RESULTS.csv [--classes wolf,centaur] [--pairs N]
      [--remeshed DIR --truth DIR] [--samples 300] [--seed 7]
  python3 scripts/pyfmaps_bench.py --check OUT SOURCE TARGET
"""

import argparse
import csv
import json
import os
import sys
import time

try:
    import numpy as np

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import meshtools as mt
except ImportError:
    print("pyfmaps_bench: NumPy is not installed (pip install numpy scipy pyfmaps in a virtual environment); skipped")
    sys.exit(0)

MASK64 = (1 << 64) - 1
SAMPLES = 300
SEED = 7


def sample_indices(n, k, seed):
    """shapespace's `registration::metrics::sample_indices`: partial Fisher-Yates with a
    splitmix64 stream, sorted; all indices when k >= n."""
    idx = list(range(n))
    if k >= n:
        return np.asarray(idx, dtype=np.int64)
    state = seed & MASK64
    for i in range(k):
        state = (state + 0x9E3779B97F4A7C15) & MASK64
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
        z ^= z >> 31
        j = i + z % (n - i)
        idx[i], idx[j] = idx[j], idx[i]
    return np.sort(np.asarray(idx[:k], dtype=np.int64))


class HeatGeodesics:
    """Crane et al. 2013 as in crates/analysis/src/registration/geodesic.rs."""

    def __init__(self, V, F):
        import scipy.sparse as sp
        import scipy.sparse.linalg as sla

        self.n, self.F = len(V), F
        p = [V[F[:, k]] for k in range(3)]
        nrm = np.cross(p[1] - p[0], p[2] - p[0])
        a2 = np.linalg.norm(nrm, axis=1)
        if not np.all(a2 > 0):
            raise ValueError("heat method: degenerate face")
        unit = nrm / a2[:, None]
        self.g = np.empty((len(F), 3, 3))
        edge_sum = 0.0
        for k in range(3):
            e = p[(k + 2) % 3] - p[(k + 1) % 3]
            self.g[:, k, :] = np.cross(unit, e) / a2[:, None]
            edge_sum += np.linalg.norm(e, axis=1).sum()
        self.area = 0.5 * a2
        rows, cols, vals = [], [], []
        for i in range(3):
            for j in range(3):
                rows.append(F[:, i])
                cols.append(F[:, j])
                vals.append(self.area * np.einsum("fd,fd->f", self.g[:, i], self.g[:, j]))
        L = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(self.n, self.n))
        h = edge_sum / (3 * len(F))
        self.time = h * h
        mass = np.zeros(self.n)
        for k in range(3):
            np.add.at(mass, F[:, k], self.area / 3.0)
        self.total_area = self.area.sum()
        self.heat = sla.splu((sp.diags(mass) + self.time * L).tocsc())
        self.poisson = sla.splu(L[1:, 1:].tocsc())

    def distances(self, sources):
        """Distance fields (n x len(sources)) from point sources; a source is a vertex index or
        (face, [b0, b1, b2]) for a barycentric point (delta spread over the corners)."""
        k = len(sources)
        delta = np.zeros((self.n, k))
        for c, s in enumerate(sources):
            if isinstance(s, tuple):
                for j in range(3):
                    delta[self.F[s[0], j], c] += s[1][j]
            else:
                delta[s, c] = 1.0
        u = self.heat.solve(delta)
        out = np.empty((self.n, k))
        for c in range(k):
            grad = np.einsum("fk,fkd->fd", u[self.F, c], self.g)
            length = np.linalg.norm(grad, axis=1)
            ok = (length > 0) & np.isfinite(length)
            X = np.zeros_like(grad)
            X[ok] = -grad[ok] / length[ok, None]
            rhs = np.zeros(self.n)
            for i in range(3):
                np.add.at(rhs, self.F[:, i], self.area * np.einsum("fd,fd->f", self.g[:, i], X))
            phi = np.zeros(self.n)
            phi[1:] = self.poisson.solve(rhs[1:])
            s = sources[c]
            if isinstance(s, tuple):
                phi -= sum(s[1][j] * phi[self.F[s[0], j]] for j in range(3))
            else:
                phi -= phi[s]
            out[:, c] = phi
        return out


def geodesic_errors(heat, samples, truth, image_face, image_bary, F2):
    """Per sample v: the heat distance on the target from truth(v) to the image (face, bary) of
    v, clamped at 0, over sqrt(area)."""
    errors = np.empty(len(samples))
    for start in range(0, len(samples), 32):
        chunk = samples[start:start + 32]
        d = heat.distances([truth(v) for v in chunk])
        for c, v in enumerate(chunk):
            t = F2[image_face[v]]
            errors[start + c] = max(float(np.dot(image_bary[v], d[t, c])), 0.0)
    return errors / np.sqrt(heat.total_area)


def vertex_to_face(F, n):
    """A face holding each vertex, with the vertex's barycentric coordinates (1 at it)."""
    face = np.full(n, -1, dtype=np.int64)
    bary = np.zeros((n, 3))
    for f in range(len(F) - 1, -1, -1):
        for k in range(3):
            face[F[f, k]] = f
    for v in range(n):
        bary[v, list(F[face[v]]).index(v)] = 1.0
    return face, bary


def read_truth(path):
    """A ground-truth CSV (vertex,face,b0,b1,b2) as a function v -> (face, [b0, b1, b2])."""
    points = {}
    with open(path) as fh:
        for row in csv.DictReader(fh):
            points[int(row["vertex"])] = (int(row["face"]), [float(row["b0"]), float(row["b1"]), float(row["b2"])])
    return lambda v: points[int(v)]


def read_landmarks(path):
    with open(path) as fh:
        return json.load(fh).get("landmarks", {})


def mesh_files(folder):
    return sorted(
        os.path.join(folder, f) for f in os.listdir(folder) if f.lower().endswith((".off", ".obj", ".ply"))
    )


def stem(path):
    return os.path.splitext(os.path.basename(path))[0]


K_PROCESS = 200


def pyfmaps_shape(path):
    """A pyFM mesh with its K_PROCESS Laplace-Beltrami eigenpairs (computed once per shape, as
    `register-bench` computes its eigenpairs once per mesh) and the seconds it took."""
    from pyFM.mesh import TriMesh

    t0 = time.perf_counter()
    mesh = TriMesh.load(path, area_normalize=True, center=True)
    mesh.process(k=K_PROCESS, verbose=False)
    return mesh, time.perf_counter() - t0


def pyfmaps_map(src_mesh, tgt_mesh, lm_src, lm_tgt):
    """The pyFM vertex map source -> target (README quick start + ZoomOut) from processed meshes
    (copied: pyFM stores descriptors on them) and the seconds of this pair's own work."""
    import copy

    from pyFM.functional import FunctionalMapping

    t0 = time.perf_counter()
    # pyFM's p2p_21 maps mesh2's vertices to mesh1: mesh1 = target, mesh2 = source
    model = FunctionalMapping(copy.deepcopy(tgt_mesh), copy.deepcopy(src_mesh))
    lm = np.stack([np.asarray(lm_tgt), np.asarray(lm_src)], axis=1)
    model.preprocess(descr_type="WKS", landmarks=lm, subsample_step=2, k_process=K_PROCESS, verbose=False)
    model.fit(K=30, w_descr=1e0, w_lap=1e-1, w_dcomm=1e0, w_orient=1e0, verbose=False)
    fm_zo = model.zoomout_refine(nit=16, step=5, verbose=False)
    p2p = np.asarray(model.get_p2p(fm_zo), dtype=np.int64)
    return p2p, time.perf_counter() - t0


def bench(args):
    try:
        import pyFM  # noqa: F401
    except ImportError:
        print("pyfmaps_bench: pyfmaps is not installed (pip install pyfmaps in a virtual environment); skipped")
        return 0
    classes = sorted(d for d in os.listdir(args.dataset) if os.path.isdir(os.path.join(args.dataset, d)))
    if args.classes:
        wanted = args.classes.split(",")
        classes = [c for c in classes if c in wanted]
    rows = []
    for cls in classes:
        folder = os.path.join(args.dataset, cls)
        files = mesh_files(folder)
        if len(files) < 2:
            continue
        lms = read_landmarks(os.path.join(folder, "landmarks.json"))
        names = sorted(lms)
        meshes = [mt.read_mesh(f) for f in files]
        # eigenpairs and heat solvers once per mesh, when a pair first needs them (--pairs)
        shapes = {}

        def shape(j):
            if j not in shapes:
                shapes[j] = pyfmaps_shape(files[j])
            return shapes[j]

        # targets: (pose index, triangulation) -> (shape, V, F, landmarks, heat, truth)
        targets = {}

        def target(j, kind):
            if (j, kind) in targets:
                return targets[(j, kind)]
            if kind == "same":
                V2, F2 = meshes[j]
                targets[(j, kind)] = (shape(j), V2, F2, [lms[n] for n in names], HeatGeodesics(V2, F2), int)
                return targets[(j, kind)]
            name = stem(files[j])
            rpath = [p for p in mesh_files(os.path.join(args.remeshed, cls)) if stem(p) == name]
            if not rpath:
                raise SystemExit("pyfmaps_bench: no remeshed %s in %s" % (name, os.path.join(args.remeshed, cls)))
            V2, F2 = mt.read_mesh(rpath[0])
            rl = read_landmarks(os.path.join(args.truth, cls, name + ".landmarks.json"))
            truth = read_truth(os.path.join(args.truth, cls, name + ".csv"))
            targets[(j, kind)] = (pyfmaps_shape(rpath[0]), V2, F2, [rl[n] for n in names], HeatGeodesics(V2, F2), truth)
            return targets[(j, kind)]

        kinds = ["same", "remeshed"] if args.remeshed else ["same"]
        for i, src in enumerate(files):
            samples = sample_indices(len(meshes[i][0]), args.samples, args.seed)
            for kind in kinds:
                for j in range(len(files)):
                    if i == j or (args.pairs and sum(r["class"] == cls and r["triangulation"] == kind for r in rows) >= args.pairs):
                        continue
                    tshape, V2, F2, tl, heat, truth = target(j, kind)
                    p2p, secs = pyfmaps_map(shape(i)[0], tshape[0], [lms[n] for n in names], tl)
                    face_of, bary_of = vertex_to_face(F2, len(V2))
                    err = geodesic_errors(heat, samples, truth, face_of[p2p], bary_of[p2p], F2)
                    row = {
                        "class": cls,
                        "source": stem(src),
                        "target": stem(files[j]),
                        "triangulation": kind,
                        "geodesic_mean": float(err.mean()),
                        "geodesic_median": float(np.median(err)),
                        # from scratch: both shapes' eigenpairs and this pair's work
                        "seconds": shape(i)[1] + tshape[1] + secs,
                        "pair_seconds": secs,
                    }
                    print(
                        "{class} {source}->{target} ({triangulation}) geo {geodesic_mean:.4f}/{geodesic_median:.4f} "
                        "{seconds:.1f}s (pair {pair_seconds:.1f}s)".format(**row),
                        flush=True,
                    )
                    rows.append(row)
    if not rows:
        print("pyfmaps_bench: no class folder with two meshes")
        return 1
    tmp = args.out + ".tmp"
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    os.replace(tmp, args.out)
    for cls, kind in sorted({(r["class"], r["triangulation"]) for r in rows}):
        sel = [r for r in rows if r["class"] == cls and r["triangulation"] == kind]
        print(
            "{} ({}): {} pairs, geodesic mean {:.4f}, median {:.4f}, {:.1f} s/pair ({:.1f} s with eigenpairs shared)".format(
                cls,
                kind,
                len(sel),
                np.mean([r["geodesic_mean"] for r in sel]),
                np.mean([r["geodesic_median"] for r in sel]),
                np.mean([r["seconds"] for r in sel]),
                np.mean([r["pair_seconds"] for r in sel]),
            )
        )
    return 0


def check(out, source, target):
    """This script's error of shapespace's correspondence against shapespace's own numbers."""
    V1, _ = mt.read_mesh(source)
    V2, F2 = mt.read_mesh(target)
    face, bary = np.zeros(len(V1), dtype=np.int64), np.zeros((len(V1), 3))
    with open(os.path.join(out, "correspondence.csv")) as fh:
        for row in csv.DictReader(fh):
            v = int(row["vertex"])
            face[v] = int(row["face"])
            bary[v] = [float(row["b0"]), float(row["b1"]), float(row["b2"])]
    with open(os.path.join(out, "metrics.json")) as fh:
        geo = json.load(fh)["metrics"]["geodesic"]
    samples = sample_indices(len(V1), SAMPLES, SEED)
    if list(samples) != geo["samples"]:
        print("check: the samples differ from metrics.json")
        return 1
    err = geodesic_errors(HeatGeodesics(V2, F2), samples, lambda v: int(v), face, bary, F2)
    diff = np.abs(err - np.asarray(geo["errors"])).max()
    print(f"check: {len(samples)} samples, mean {err.mean():.6f} (shapespace {np.mean(geo['errors']):.6f}), max |difference| {diff:.2e}")
    return 0 if diff < 1e-9 else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset", nargs="?", help="folder of class folders (as register-bench)")
    ap.add_argument("--out", help="results CSV (written atomically)")
    ap.add_argument("--classes", help="comma-separated class folders (default: all)")
    ap.add_argument("--pairs", type=int, help="at most this many ordered pairs per class (default: all)")
    ap.add_argument("--remeshed", help="folder of remeshed poses DIR/CLASS/NAME.off (register-bench --remeshed)")
    ap.add_argument("--truth", help="register-bench's OUT/truth folder (ground truth and markers of the remeshed poses)")
    ap.add_argument("--samples", type=int, default=SAMPLES, help="sampled source vertices (default 300)")
    ap.add_argument("--seed", type=int, default=SEED, help="seed of the sample (default 7)")
    ap.add_argument("--check", nargs=3, metavar=("OUT", "SOURCE", "TARGET"))
    args = ap.parse_args()
    if bool(args.remeshed) != bool(args.truth):
        ap.error("--remeshed and --truth go together")
    if args.check:
        return check(*args.check)
    if not args.dataset or not args.out:
        ap.error("DATASET and --out are required (or --check)")
    return bench(args)


if __name__ == "__main__":
    sys.exit(main())
