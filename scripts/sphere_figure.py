#!/usr/bin/env python3
"""Writes docs/sphere_area_distortion.png: the area distortion of the conformal and the
area-preserving sphere map of an ellipsoid of revolution (semi-axes 1, 1, 2; an icosphere of
10,242 vertices), as `shapespace param --domain sphere --plots` draws it.

Usage: python3 scripts/sphere_figure.py [--shapespace PATH]  (default: target/release/shapespace,
built with `cargo build --release`). Standard library only.
"""
import argparse
import math
import pathlib
import shutil
import subprocess
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent


def icosphere(subdivisions):
    t = (1 + 5**0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]

    def unit(p):
        n = math.sqrt(sum(x * x for x in p))
        return [x / n for x in p]

    v = [unit(p) for p in v]
    for _ in range(subdivisions):
        middle = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                v.append(unit([(v[a][i] + v[b][i]) / 2 for i in range(3)]))
                middle[key] = len(v) - 1
            return middle[key]

        faces = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = faces
    return v, f


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapespace", default=str(ROOT / "target" / "release" / "shapespace"))
    args = parser.parse_args()
    v, f = icosphere(5)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        mesh = tmp / "ellipsoid.obj"
        with open(mesh, "w") as out:
            for x, y, z in v:
                out.write(f"v {x!r} {y!r} {2 * z!r}\n")
            for a, b, c in f:
                out.write(f"f {a + 1} {b + 1} {c + 1}\n")
        subprocess.run([args.shapespace, "param", str(mesh), "--domain", "sphere",
                        "--out", str(tmp / "ellipsoid_ap.obj"), "--plots", str(tmp / "plots")],
                       check=True)
        shutil.copyfile(tmp / "plots" / "area_distortion.png", ROOT / "docs" / "sphere_area_distortion.png")
    print("wrote docs/sphere_area_distortion.png")


if __name__ == "__main__":
    main()
