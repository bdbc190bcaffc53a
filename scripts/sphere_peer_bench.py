#!/usr/bin/env python3
"""Spherical conformal maps side by side: shapespace and Choi's spherical-conformal-map.

Choi, Lam, Lui, "FLASH: Fast Landmark Aligned Spherical Harmonic Parameterization for Genus-0
Closed Brain Surfaces", SIAM J. Imaging Sci. 8(1), 2015; the authors' MATLAB code
(github.com/garyptchoi/spherical-conformal-map, Apache-2.0) runs in GNU Octave. Neither that
code nor the meshes are part of this repository: give the folder of a local copy with --choi.

Per mesh, in one run: wall seconds of `shapespace conformal MESH --domain sphere` (process
start and file I/O included) and of `spherical_conformal_map(v, f)` inside Octave (timed with
tic/toc, Octave's start and the file I/O excluded), then the same angle-distortion measure on
both outputs: per corner, |angle of the 3D triangle - angle of the straight triangle between
the three image points|, in degrees, mean and 95th percentile over all corners; and the faces
whose image is flipped (det(a, b, c) of the three image points against the orientation of the
majority of the faces, computed from edge differences so that its rounding scales with the
triangle; a reflected map counts as unflipped; shapespace's own count uses exact predicates).

`--ellipsoid LEVEL` adds an ellipsoid 1:1.5:2 made from an icosphere subdivided LEVEL times
(10 * 4^LEVEL + 2 vertices; 7 gives 163,842).

Usage: python3 scripts/sphere_peer_bench.py --choi DIR [--octave octave] [--ellipsoid 7] MESH...
(needs `cargo build --release -p shapespace-cli`; the binary is taken from $CARGO_TARGET_DIR,
default target/)
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from meshtools import read_mesh, write_obj  # noqa: E402


def icosphere(level):
    t = (1.0 + 5.0**0.5) / 2.0
    V = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    F = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(level):
        mid = {}
        newF = []

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = V[a] + V[b]
                V.append(p / np.linalg.norm(p))
                mid[key] = len(V) - 1
            return mid[key]

        for a, b, c in F:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            newF += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        F = newF
    return np.array(V), np.array(F, dtype=np.int64)


def corner_angles(P, F):
    out = np.empty((len(F), 3))
    for k in range(3):
        a, b, c = P[F[:, k]], P[F[:, (k + 1) % 3]], P[F[:, (k + 2) % 3]]
        u, w = b - a, c - a
        cosang = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        out[:, k] = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0)))
    return out


def distortion(V, F, S):
    # (a face whose image has coincident corners has no angles: left out of the statistics,
    # counted with the flipped ones below, det = 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(corner_angles(V, F) - corner_angles(S, F)).ravel()
    err = err[np.isfinite(err)]
    # det(a, b, c) = a . ((b - a) x (c - a)): the differences first, so that the rounding error
    # scales with the triangle (the crowded images of limbs have det of 1e-21 and less)
    a = S[F[:, 0]]
    det = np.einsum("ij,ij->i", a, np.cross(S[F[:, 1]] - a, S[F[:, 2]] - a))
    flipped = min(int((det <= 0).sum()), int((det >= 0).sum()))
    return float(np.mean(err)), float(np.percentile(err, 95)), flipped


def run_shapespace(binary, mesh_path, tmp):
    out = os.path.join(tmp, "ss.obj")
    report = os.path.join(tmp, "ss.json")
    start = time.perf_counter()
    r = subprocess.run([binary, "conformal", mesh_path, "--domain", "sphere", "--out", out, "--report", report],
                       capture_output=True, text=True)
    wall = time.perf_counter() - start
    if r.returncode != 0:
        return None, wall, r.stderr.strip().splitlines()[-1] if r.stderr else "failed"
    S, _ = read_mesh(out)
    return np.asarray(S, float), wall, ""


def run_choi(octave, choi, V, F, tmp):
    np.savetxt(os.path.join(tmp, "v.txt"), V, fmt="%.17g")
    np.savetxt(os.path.join(tmp, "f.txt"), F + 1, fmt="%d")
    script = (
        f"addpath('{os.path.join(choi, 'mfile')}'); cd('{tmp}'); v = load('v.txt'); f = load('f.txt'); "
        "tic; map = spherical_conformal_map(v, f); t = toc; "
        "dlmwrite('map.txt', map, 'precision', 17); fid = fopen('t.txt', 'w'); fprintf(fid, '%.6f', t); fclose(fid);"
    )
    r = subprocess.run([octave, "--no-gui", "--quiet", "--eval", script], capture_output=True, text=True)
    if r.returncode != 0 or not os.path.exists(os.path.join(tmp, "map.txt")):
        return None, float("nan"), (r.stderr.strip().splitlines() or ["failed"])[-1]
    S = np.loadtxt(os.path.join(tmp, "map.txt"), delimiter=",")
    with open(os.path.join(tmp, "t.txt")) as fh:
        t = float(fh.read())
    return S, t, ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--choi", required=True, help="folder of a local copy of garyptchoi/spherical-conformal-map")
    ap.add_argument("--octave", default="octave")
    ap.add_argument("--ellipsoid", type=int, action="append", default=[])
    ap.add_argument("meshes", nargs="*")
    args = ap.parse_args()
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    binary = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(root, "target")), "release", "shapespace")
    for what, path in (("shapespace", binary), ("octave", shutil.which(args.octave) or "")):
        if not os.path.exists(path):
            print(f"SKIPPED: {what} not found ({path or args.octave})", file=sys.stderr)
            return 2
    if not os.path.exists(os.path.join(args.choi, "mfile", "spherical_conformal_map.m")):
        print(f"SKIPPED: {args.choi}/mfile/spherical_conformal_map.m not found", file=sys.stderr)
        return 2
    cases = []
    for level in args.ellipsoid:
        V, F = icosphere(level)
        cases.append((f"ellipsoid 1:1.5:2 (icosphere level {level})", V * np.array([1.0, 1.5, 2.0]), F))
    for path in args.meshes:
        V, F = read_mesh(path)
        cases.append((os.path.basename(path), np.asarray(V, float), np.asarray(F, np.int64)))
    print("| mesh | V | shapespace s | Choi s (in Octave) | angle error ° mean / p95, shapespace | Choi | flipped faces shapespace / Choi |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, V, F in cases:
        with tempfile.TemporaryDirectory() as tmp:
            mesh_path = os.path.join(tmp, "in.obj")
            write_obj(mesh_path, V, F, decimals=12)
            S1, t1, e1 = run_shapespace(binary, mesh_path, tmp)
            S2, t2, e2 = run_choi(args.octave, args.choi, V, F, tmp)
        if S2 is not None and not np.isfinite(S2).all():
            S2, e2 = None, f"{int((~np.isfinite(S2).all(axis=1)).sum())} non-finite positions"
        d1 = distortion(V, F, S1) if S1 is not None else None
        d2 = distortion(V, F, S2) if S2 is not None else None
        fmt = lambda d, e: f"{d[0]:.2f} / {d[1]:.2f}" if d else f"failed: {e[:60]}"
        flips = f"{d1[2] if d1 else '-'} / {d2[2] if d2 else '-'}"
        print(f"| {name} | {len(V)} | {t1:.2f} | {t2:.2f} | {fmt(d1, e1)} | {fmt(d2, e2)} | {flips} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
