#!/usr/bin/env python3
"""Synthesize datasets/faces/: ICT FaceKit faces (identities x expressions) as disks.

Model (ICT FaceKit, MIT, see datasets/faces/model/LICENSE):
    V = N + sum_{k<40} a_k (identity_k - N) + sum_j w_j (expr_j - N)
restricted to the `face_full` region (vertices 0..9408, 18,460 triangles), with
the two eye openings and the mouth opening closed by a centroid fan. Units: cm
(+y up, face looking toward +z).

Identity i uses a = numpy.random.default_rng(i).standard_normal(40) (the
natural N(0,1) scale of the upstream sampler; nothing is tuned). The exact
coefficients are also written to datasets/faces/identity_coefficients.json.

Vertex order in every output face: 0..9408 = ICT vertices 0..9408, then
9409 = fan center of eye_xpos, 9410 = fan center of eye_xneg, 9411 = fan
center of the mouth (each placed at the mean of its loop's vertices, per face).
Triangles: the 18,460 face_full triangles followed by the fans
(L[j+1], L[j], c) for eye_xpos (42), eye_xneg (42), mouth (74).

Usage:
    python3 scripts/make_faces.py [--source ../shared/datasets] [--from-shipped]
The full ICT data is read from SOURCE/ict_facekit/ if it exists (and the
shipped subset datasets/faces/model/ is (re)written from it); otherwise, or
with --from-shipped, the shipped subset is used. Both give identical files.
"""

import argparse
import json
import os
import shutil
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import meshtools as mt  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(REPO, "datasets", "faces")
MODEL = os.path.join(OUT, "model")

N_REGION = 9409          # face_full: vertices 0..9408
N_MODES = 40             # identity modes used
N_IDENTITIES = 10
INNER_LOOPS = ["eye_xpos", "eye_xneg", "mouth"]

# FACS / Ekman weights, every _L/_R pair with the same weight.
EXPRESSIONS = {
    "neutral": {},
    "happy": {"mouthSmile_L": 1.0, "mouthSmile_R": 1.0,
              "cheekSquint_L": 1.0, "cheekSquint_R": 1.0},
    "sad": {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0,
            "browDown_L": 0.5, "browDown_R": 0.5,
            "mouthFrown_L": 1.0, "mouthFrown_R": 1.0,
            "mouthShrugLower": 0.5},
    "surprise": {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0,
                 "browOuterUp_L": 1.0, "browOuterUp_R": 1.0,
                 "eyeWide_L": 1.0, "eyeWide_R": 1.0,
                 "jawOpen": 0.3},
}
EXPR_ORDER = ["neutral", "happy", "sad", "surprise"]


def needed_expressions():
    names = []
    for e in EXPR_ORDER:
        for n in EXPRESSIONS[e]:
            if n not in names:
                names.append(n)
    return names


def load_full(src):
    d = os.path.join(src, "ict_facekit")
    N = np.load(os.path.join(d, "neutral_vertices_f64.npy"))[:N_REGION]
    ident = np.load(os.path.join(d, "identity_deltas.npy"), mmap_mode="r")[:N_MODES, :N_REGION]
    expr_all = np.load(os.path.join(d, "expression_deltas.npy"), mmap_mode="r")
    all_names = json.load(open(os.path.join(d, "names.json")))["expressions"]
    names = needed_expressions()
    expr = np.stack([expr_all[all_names.index(n), :N_REGION] for n in names])
    T = np.load(os.path.join(d, "face_full_triangles.npy"))
    loops_all = json.load(open(os.path.join(d, "face_region_boundary_loops.json")))["face_full"]
    loops = {k: loops_all[k]["vertices"] for k in INNER_LOOPS + ["outer"]}
    model = {
        "neutral": np.ascontiguousarray(N, dtype="<f8"),
        "identity": np.ascontiguousarray(ident, dtype="<f4"),
        "expr": np.ascontiguousarray(expr, dtype="<f4"),
        "expr_names": names,
        "triangles": np.ascontiguousarray(T, dtype="<i4"),
        "loops": loops,
    }
    return model, d


def write_model(model, ict_dir):
    os.makedirs(MODEL, exist_ok=True)
    np.save(os.path.join(MODEL, "neutral_vertices_f64.npy"), model["neutral"])
    np.save(os.path.join(MODEL, "identity_deltas_f32.npy"), model["identity"])
    np.save(os.path.join(MODEL, "expression_deltas_f32.npy"), model["expr"])
    np.save(os.path.join(MODEL, "face_full_triangles_i32.npy"), model["triangles"])
    with open(os.path.join(MODEL, "model.json"), "w") as fh:
        json.dump({
            "description": "Subset of the ICT FaceKit light model (MIT), face_full region only. "
                           "neutral_vertices_f64.npy: (9409,3) neutral vertices 0..9408 (cm). "
                           "identity_deltas_f32.npy: (40,9409,3) identity_k - neutral for k=0..39. "
                           "expression_deltas_f32.npy: (n,9409,3) expr - neutral, names below. "
                           "face_full_triangles_i32.npy: (18460,3) 0-based triangles. "
                           "loops: ordered boundary loops of face_full (boundary half-edge direction).",
            "upstream": "https://github.com/ICT-VGL/ICT-FaceKit commit da5f95a607f5e6b37755b38d3385d7f2853732e5 FaceXModel/",
            "expression_names": model["expr_names"],
            "loops": model["loops"],
        }, fh, indent=1)
    for f in ("LICENSE", "CREDITS.md"):
        shutil.copyfile(os.path.join(ict_dir, "original", f), os.path.join(MODEL, f))


def load_shipped():
    meta = json.load(open(os.path.join(MODEL, "model.json")))
    return {
        "neutral": np.load(os.path.join(MODEL, "neutral_vertices_f64.npy")),
        "identity": np.load(os.path.join(MODEL, "identity_deltas_f32.npy")),
        "expr": np.load(os.path.join(MODEL, "expression_deltas_f32.npy")),
        "expr_names": meta["expression_names"],
        "triangles": np.load(os.path.join(MODEL, "face_full_triangles_i32.npy")),
        "loops": {k: meta["loops"][k] for k in INNER_LOOPS + ["outer"]},
    }


def identity_coefficients(i):
    return np.random.default_rng(i).standard_normal(N_MODES)


def synthesize(model, a, weights):
    V = model["neutral"].astype(np.float64).copy()
    V += np.tensordot(a, model["identity"].astype(np.float64), axes=(0, 0))
    for name, w in weights.items():
        V += w * model["expr"][model["expr_names"].index(name)].astype(np.float64)
    return V


def fill_holes(V, T, loops):
    """Append one fan center per inner loop (at the loop mean) and the fan
    triangles (L[j+1], L[j], c). The loops follow the boundary half-edge
    direction of T, so each fan edge L[j+1]->L[j] is the reverse of the
    existing half-edge L[j]->L[j+1]: the orientation is consistent."""
    Vs = [V]
    Fs = [np.asarray(T, dtype=np.int64)]
    n = len(V)
    for k, name in enumerate(INNER_LOOPS):
        L = np.asarray(loops[name], dtype=np.int64)
        c = n + k
        Vs.append(V[L].mean(axis=0, keepdims=True))
        Fs.append(np.stack([np.roll(L, -1), L, np.full_like(L, c)], axis=1))
    return np.concatenate(Vs), np.concatenate(Fs)


def landmarks(V0, loops):
    """Geometric landmark rules on the neutral template (see datasets/README.md)."""
    x, y, z = V0[:, 0], V0[:, 1], V0[:, 2]
    n = len(V0)
    mid = np.where(np.abs(x) < 0.3)[0]
    nose = int(mid[np.argmax(z[mid])])
    mouth = np.asarray(loops["mouth"])
    mouth_y = y[mouth].mean()
    chin_c = mid[y[mid] < mouth_y - 1.5]
    chin = int(chin_c[np.argmax(z[chin_c])])
    outer = np.asarray(loops["outer"])
    boundary = int(outer[np.argmin(y[outer])])
    lm = {}
    for eye in ("eye_xpos", "eye_xneg"):
        L = np.asarray(loops[eye])
        ext_pos = int(L[np.argmax(x[L])])
        ext_neg = int(L[np.argmin(x[L])])
        if eye == "eye_xpos":
            lm[eye + "_outer"], lm[eye + "_inner"] = ext_pos, ext_neg
        else:
            lm[eye + "_outer"], lm[eye + "_inner"] = ext_neg, ext_pos
    lm["mouth_xpos"] = int(mouth[np.argmax(x[mouth])])
    lm["mouth_xneg"] = int(mouth[np.argmin(x[mouth])])
    lm["nose_tip"] = nose
    lm["chin"] = chin
    assert all(0 <= v < n for v in lm.values())
    return {"center": nose, "boundary": boundary, "landmarks": lm}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", default=os.path.join(REPO, "..", "shared", "datasets"),
                    help="folder holding ict_facekit/ (default ../shared/datasets relative to the repo)")
    ap.add_argument("--from-shipped", action="store_true", help="use datasets/faces/model/ only")
    ap.add_argument("--out", default=OUT, help="output folder (default datasets/faces)")
    args = ap.parse_args()

    full = os.path.join(args.source, "ict_facekit", "identity_deltas.npy")
    if not args.from_shipped and os.path.exists(full):
        model, ict_dir = load_full(args.source)
        write_model(model, ict_dir)
        print("model: full ICT data from", os.path.abspath(os.path.dirname(full)), "(subset rewritten)")
    else:
        model = load_shipped()
        print("model: shipped subset", MODEL)

    out = args.out
    os.makedirs(out, exist_ok=True)
    shutil.copyfile(os.path.join(MODEL, "LICENSE"), os.path.join(out, "LICENSE_ICT-FaceKit_MIT.txt"))
    T, loops = model["triangles"], model["loops"]
    labels = ["file,identity,expression"]
    coeffs = {}
    report = []
    for i in range(N_IDENTITIES):
        a = identity_coefficients(i)
        coeffs["id%02d" % i] = [round(float(v), 12) for v in a]
        for e in EXPR_ORDER:
            V = synthesize(model, a, EXPRESSIONS[e])
            Vd, Fd = fill_holes(V, T, loops)
            Vd = np.round(Vd, 6)  # what is written
            name = "id%02d_%s.obj" % (i, e)
            mt.write_obj(os.path.join(out, name), Vd, Fd, header_lines=(
                "ICT FaceKit (MIT, (c) 2020 USC ICT) face_full + filled eyes/mouth; units cm; "
                "identity %d (seed %d, 40 modes), expression %s" % (i, i, e),
                "generated by scripts/make_faces.py; see datasets/README.md"))
            labels.append("%s,%d,%s" % (name, i, e))
            t = mt.check_disk(Vd, Fd, name)
            areas = mt.triangle_areas(Vd, Fd)
            fan = areas[len(T):]
            # flip check: cosine between each fan triangle's normal and its fan's total normal
            Ff = Fd[len(T):]
            nrm = np.cross(Vd[Ff[:, 1]] - Vd[Ff[:, 0]], Vd[Ff[:, 2]] - Vd[Ff[:, 0]])
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            cmin = 1.0
            for c in np.unique(Ff[:, 2]):
                m = nrm[Ff[:, 2] == c]
                tot = m.sum(axis=0)
                cmin = min(cmin, float((m @ (tot / np.linalg.norm(tot))).min()))
            report.append((name, t["V"], t["F"], float(areas.min()), float(fan.min()),
                           float(fan.max()), cmin))
    with open(os.path.join(out, "labels.csv"), "w", newline="\n") as fh:
        fh.write("\n".join(labels) + "\n")
    with open(os.path.join(out, "identity_coefficients.json"), "w") as fh:
        json.dump({"rule": "a = numpy.random.default_rng(i).standard_normal(40) for identity i",
                   "coefficients": coeffs}, fh, indent=1)
    V0 = model["neutral"].astype(np.float64)
    lm = landmarks(V0, loops)
    with open(os.path.join(out, "landmarks.json"), "w") as fh:
        json.dump(lm, fh, indent=1)
    print("landmarks:", json.dumps(lm))
    print("%-22s %6s %6s %12s %12s %12s %8s" % ("file", "V", "F", "min area", "min fan",
                                                 "max fan", "fan cos"))
    for r in report:
        print("%-22s %6d %6d %12.3e %12.3e %12.3e %8.3f" % r)
    nv = {r[1] for r in report}
    assert len(nv) == 1, nv
    print("all %d faces: oriented manifold disks, V = %d" % (len(report), nv.pop()))


if __name__ == "__main__":
    main()
