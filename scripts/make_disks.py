#!/usr/bin/env python3
"""Copy a few classic disk-topology meshes, byte for byte, into datasets/disks/,
with their license / provenance files; the alligator, a disk whose conformal image is
beyond double precision (its tail), goes to datasets/beyond_f64/ instead.

Usage: python3 scripts/make_disks.py [--source ../shared/datasets]
"""

import argparse
import hashlib
import os
import shutil

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(REPO, "datasets", "disks")

# (source folder, file, path relative to datasets/disks)
MESHES = [
    ("libigl_tutorial_data", "camelhead.off", "camelhead.off"),
    ("libigl_tutorial_data", "lion.off", "lion.off"),
    ("libigl_tutorial_data", "face.obj", "face.obj"),
    ("geometry_central_assets", "cat_head.obj", "cat_head.obj"),
    ("common_3d_test_models", "woody.obj", "woody.obj"),
    ("common_3d_test_models", "alligator.obj", "../beyond_f64/alligator.obj"),
    ("goast", "plate/plate121.ply", "plate121.ply"),
    ("goast", "plate/plate121_rolledA.ply", "plate121_rolledA.ply"),
]
# license / attribution files shipped next to the meshes
NOTICES = [
    ("libigl_tutorial_data", "README_upstream.md", "libigl-tutorial-data_README_upstream.md"),
    ("geometry_central_assets", "geometry-central_LICENSE_MIT.txt", "geometry-central_LICENSE_MIT.txt"),
    ("common_3d_test_models", "README_upstream.md", "common-3d-test-models_README_upstream.md"),
    ("common_3d_test_models", "README_upstream.md", "../beyond_f64/common-3d-test-models_README_upstream.md"),
    ("goast", "GOAST_LICENSE_MPL2.txt", "GOAST_LICENSE_MPL2.txt"),
    ("goast", "README_upstream.md", "GOAST_data_README_upstream.md"),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--source", default=os.path.join(REPO, "..", "shared", "datasets"))
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for folder, src, dst in MESHES + NOTICES:
        p = os.path.join(args.source, folder, src)
        q = os.path.normpath(os.path.join(args.out, dst))
        os.makedirs(os.path.dirname(q), exist_ok=True)
        shutil.copyfile(p, q)
        h = hashlib.sha256(open(q, "rb").read()).hexdigest()
        print("%-45s <- %s/%s  sha256 %s" % (dst, folder, src, h[:16]))


if __name__ == "__main__":
    main()
