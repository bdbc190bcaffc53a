#!/usr/bin/env python3
"""Compute topology statistics of every mesh shipped under datasets/ and check
the generated sets.

Writes datasets/stats.json: {path relative to datasets/: {"V", "F", "E",
"boundary_loops", "euler", "components", "class", "oriented", "manifold"}},
and replaces the table between the `stats:begin` / `stats:end` markers of
datasets/README.md. The topology code is scripts/meshtools.py (independent of
the Rust crates), see `meshtools.topology` for the definitions.

Checks (exit status 1 on failure):
 * every face (datasets/faces/*.obj) and pose (datasets/poses/*/*.off) is one
   component, manifold, consistently oriented, with one boundary loop and
   chi = 1, with no unreferenced vertex;
 * vertex and face counts are identical within each set, and so are the
   face lists (vertex i corresponds to vertex i);
 * landmark indices are in range, the `boundary` vertex is on the boundary
   and the `center` and landmark vertices are interior;
 * the minimum triangle area (reported) is > 0.

Usage: python3 scripts/make_stats.py
"""

import glob
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import meshtools as mt  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
D = os.path.join(REPO, "datasets")


def set_of(rel):
    parts = rel.split("/")
    if parts[0] == "poses":
        return "poses/" + parts[1]
    return parts[0]


def main():
    paths = sorted(glob.glob(os.path.join(D, "**", "*.*"), recursive=True))
    paths = [p for p in paths if os.path.splitext(p)[1].lower() in (".obj", ".off", ".ply")]
    stats, rows, failures = {}, [], []
    sets = {}
    for p in paths:
        rel = os.path.relpath(p, D).replace(os.sep, "/")
        V, F = mt.read_mesh(p)
        t = mt.topology(V, F)
        amin = float(mt.triangle_areas(V, F).min())
        stats[rel] = {k: t[k] for k in ("V", "F", "E", "boundary_loops", "euler", "components",
                                        "class", "oriented", "manifold")}
        if t["V_file"] != t["V"]:
            stats[rel]["V_file"] = t["V_file"]
        rows.append((rel, t, amin, os.path.getsize(p)))
        if not (t["class"] == "disk" and t["oriented"] and t["V"] == t["V_file"]):
            failures.append("%s: not an oriented disk without unreferenced vertices: %r" % (rel, t))
        if amin <= 0:
            failures.append("%s: zero-area triangle" % rel)
        sets.setdefault(set_of(rel), []).append((rel, V, F))
    # consistency within each set
    for s, items in sets.items():
        F0 = items[0][2]
        for rel, V, F in items:
            if len(V) != len(items[0][1]) or not np.array_equal(F, F0):
                failures.append("%s: vertex count or faces differ from %s" % (rel, items[0][0]))
    # landmarks
    for lmf in [os.path.join(D, "faces", "landmarks.json")] + sorted(
            glob.glob(os.path.join(D, "poses", "*", "landmarks.json"))):
        lm = json.load(open(lmf))
        rel = os.path.relpath(os.path.dirname(lmf), D).replace(os.sep, "/")
        s = set_of(rel + "/x")
        _, V, F = sets[s][0]
        bverts = set(v for loop in mt.boundary_loops(F) for v in loop)
        if lm["boundary"] not in bverts:
            failures.append("%s: boundary vertex %d is not on the boundary" % (lmf, lm["boundary"]))
        for name, v in [("center", lm["center"])] + list(lm["landmarks"].items()):
            if not (0 <= v < len(V)) or v in bverts:
                failures.append("%s: %s = %d is not an interior vertex" % (lmf, name, v))
    with open(os.path.join(D, "stats.json"), "w", newline="\n") as fh:
        json.dump(stats, fh, indent=1, sort_keys=True)
        fh.write("\n")
    # markdown table
    lines = ["| file | V | F | E | boundary loops | χ | components | oriented | class | min triangle area | bytes |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for rel, t, amin, size in rows:
        lines.append("| %s | %d | %d | %d | %d | %d | %d | %s | %s | %.2e | %d |" % (
            rel, t["V"], t["F"], t["E"], t["boundary_loops"], t["euler"], t["components"],
            "yes" if t["oriented"] else "NO", t["class"], amin, size))
    table = "\n".join(lines)
    readme = os.path.join(D, "README.md")
    if os.path.exists(readme):
        txt = open(readme).read()
        a, b = "<!-- stats:begin -->", "<!-- stats:end -->"
        if a in txt and b in txt:
            txt = txt[:txt.index(a) + len(a)] + "\n" + table + "\n" + txt[txt.index(b):]
            open(readme, "w", newline="\n").write(txt)
    print(table)
    print()
    print("%d meshes; sets: %s" % (len(rows), {s: len(v) for s, v in sets.items()}))
    if failures:
        print("FAILURES:")
        print("\n".join(failures))
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
