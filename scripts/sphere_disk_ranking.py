#!/usr/bin/env python3
"""Rank a set of closed genus-0 meshes by both routes and compare the rankings.

The sphere route: `shapespace distances MESH... --domain sphere`. The cut-disk route
(docs/bodies-and-seams.md): `shapespace prepare MESH --seam N` for each mesh, then
`shapespace distances DISK... --domain disk --invariance rotation`. Prints one Markdown row per
pair (both distances and seconds, or the pair's status), the Spearman rank correlation of the
pairs both routes converged on (all pairs, and within each class: the name without its
trailing digits), and for each route the share of (within-class, between-class) pairs of
distances that are ordered within < between (1.0: the classes separate).

With `--debias` both runs subtract each target's self-cost (`distances --debias`: the distance
√max(0, c(a, b) − c(b, b)) of distances.csv, one extra solve per shape) and the table and the
statistics use those distances.

Usage: scripts/sphere_disk_ranking.py OUT MESH... [--seam N] [--pair-time-limit S] [--debias]
(needs `cargo build --release -p shapespace-cli`; the binary is taken from $CARGO_TARGET_DIR,
default target/). Meshes are read, never written; everything goes to OUT. Both runs resume
(`distances --resume`): a stopped script, or the same `distances` commands run by hand into
OUT/sphere and OUT/disk (in parallel, say), go on where they stopped; closed heads with two
classes: `scripts/ict_heads.py`.
"""

import csv
import math
import os
import re
import subprocess
import sys


def ranks(values):
    order = sorted(range(len(values)), key=lambda i: values[i])
    r = [0.0] * len(values)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and values[order[j + 1]] == values[order[i]]:
            j += 1
        for k in range(i, j + 1):
            r[order[k]] = (i + j) / 2.0 + 1.0
        i = j + 1
    return r


def spearman(x, y):
    if len(x) < 3:
        return float("nan")
    rx, ry = ranks(x), ranks(y)
    mx, my = sum(rx) / len(rx), sum(ry) / len(ry)
    sxy = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    sxx = sum((a - mx) ** 2 for a in rx)
    syy = sum((b - my) ** 2 for b in ry)
    return sxy / math.sqrt(sxx * syy) if sxx > 0 and syy > 0 else float("nan")


def klass(name):
    return re.sub(r"\d+$", "", name)


def read_pairs(path):
    out = {}
    if not os.path.exists(path):
        return out
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            key = tuple(sorted((row["a"], row["b"])))
            d = float(row["distance"]) if row["distance"] not in ("", "NaN") else float("nan")
            out[key] = (d, float(row["seconds"] or "nan"), row["status"].split(":")[0])
    return out


def with_matrix(pairs, path):
    """pairs with each distance replaced by distances.csv's entry (the debiased one)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    names = rows[0][1:]
    matrix = {(r[0], names[j]): float(v) for r in rows[1:] for j, v in enumerate(r[1:])}
    return {k: (matrix.get(k, float("nan")) if math.isfinite(d) else d, s, st) for k, (d, s, st) in pairs.items()}


def separation(pairs):
    within = [d for (a, b), (d, _, _) in pairs.items() if klass(a) == klass(b) and math.isfinite(d)]
    between = [d for (a, b), (d, _, _) in pairs.items() if klass(a) != klass(b) and math.isfinite(d)]
    if not within or not between:
        return float("nan")
    return sum(w < b for w in within for b in between) / (len(within) * len(between))


def main():
    args = sys.argv[1:]
    seam, limit = "1", None
    if "--seam" in args:
        i = args.index("--seam")
        seam = args[i + 1]
        del args[i : i + 2]
    debias = "--debias" in args
    if debias:
        args.remove("--debias")
    if "--pair-time-limit" in args:
        i = args.index("--pair-time-limit")
        limit = args[i + 1]
        del args[i : i + 2]
    if len(args) < 3:
        sys.exit(__doc__)
    out, meshes = args[0], args[1:]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    binary = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(root, "target")), "release", "shapespace")
    if not os.access(binary, os.X_OK):
        sys.exit(f"{binary} not found: run cargo build --release -p shapespace-cli first")
    for m in meshes:
        if not os.path.exists(m):
            sys.exit(f"SKIPPED: {m} not found")
    os.makedirs(os.path.join(out, "disks"), exist_ok=True)
    extra = (["--pair-time-limit", limit] if limit else []) + (["--debias"] if debias else [])
    disks = []
    for m in meshes:
        name = os.path.splitext(os.path.basename(m))[0]
        disk = os.path.join(out, "disks", name + ".obj")
        subprocess.run([binary, "prepare", m, "--out", disk, "--seam", seam], check=True, capture_output=True)
        disks.append(disk)
    runs = {
        "sphere": [binary, "distances", *meshes, "--domain", "sphere", "--out", os.path.join(out, "sphere"), "--quiet"],
        "disk": [binary, "distances", *disks, "--domain", "disk", "--invariance", "rotation", "--out",
                 os.path.join(out, "disk"), "--quiet"],
    }
    for cmd in runs.values():
        subprocess.run(cmd + extra + ["--resume"], capture_output=True)
    sphere = read_pairs(os.path.join(out, "sphere", "pairs.csv")) or read_pairs(
        os.path.join(out, "sphere", "pairs.partial.csv"))
    disk = read_pairs(os.path.join(out, "disk", "pairs.csv")) or read_pairs(os.path.join(out, "disk", "pairs.partial.csv"))
    if debias:
        sphere = with_matrix(sphere, os.path.join(out, "sphere", "distances.csv"))
        disk = with_matrix(disk, os.path.join(out, "disk", "distances.csv"))
    print("| pair | sphere d | sphere s | disk d | disk s |")
    print("|---|---:|---:|---:|---:|")
    for key in sorted(set(sphere) | set(disk)):
        cells = []
        for route in (sphere, disk):
            d, s, status = route.get(key, (float("nan"), float("nan"), "not run"))
            cells += [f"{d:.5f}" if math.isfinite(d) else status, f"{s:.1f}"]
        print(f"| {key[0]}–{key[1]} | " + " | ".join(cells) + " |")
    both = [k for k in sphere if k in disk and math.isfinite(sphere[k][0]) and math.isfinite(disk[k][0])]
    print(f"\nSpearman rho, all {len(both)} pairs with both distances: "
          f"{spearman([sphere[k][0] for k in both], [disk[k][0] for k in both]):.3f}")
    for c in sorted({klass(a) for a, _ in both} | {klass(b) for _, b in both}):
        inside = [k for k in both if klass(k[0]) == c and klass(k[1]) == c]
        if inside:
            rho = spearman([sphere[k][0] for k in inside], [disk[k][0] for k in inside])
            print(f"Spearman rho within {c}: {rho:.3f} ({len(inside)} pairs)")
    print(f"class separation (share of within < between): sphere {separation(sphere):.3f}, disk {separation(disk):.3f}")


if __name__ == "__main__":
    main()
