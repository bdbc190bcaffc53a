#!/usr/bin/env bash
# The disk map over a corpus of real meshes: every mesh file under DIR... (default: the outside
# faces, lion poses, GOAST, libigl, geometry-central, common-3d-test-models and TOSCA folders of
# the shared datasets, $SHAPESPACE_DATA, else ../shared/datasets beside the repository) is made a
# disk by `shapespace prepare` (closed surfaces with `--seam SEAM`, default 1) and mapped by
# `shapespace conformal`. Prints one Markdown row per mesh: vertices, outcome (the construction
# that gave the map, a region repair and how many vertices it moved, or the refusal) and seconds.
# Usage: scripts/disk_corpus.sh [DIR...]   (SEAM=k to change the seam; needs
# `cargo build --release` first; the binary is taken from $CARGO_TARGET_DIR, default target/)
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
data=${SHAPESPACE_DATA:-$root/../shared/datasets}
seam=${SEAM:-1}
bin=${CARGO_TARGET_DIR:-$root/target}/release/shapespace
if [ $# -eq 0 ]; then
  set -- "$data"/outside/facefuns "$data"/outside/sumner_face_poses "$data"/outside/lion_poses \
    "$data"/goast/faces "$data"/goast/cactus "$data"/goast/finger "$data"/goast/plate \
    "$data"/libigl_tutorial_data "$data"/geometry_central_assets "$data"/common_3d_test_models \
    "$data"/tosca
fi
if [ ! -x "$bin" ]; then
  echo "$bin not found: run cargo build --release first" >&2
  exit 2
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "| mesh | V | outcome | s |"
echo "|---|---:|---|---:|"
for dir in "$@"; do
  if [ ! -d "$dir" ]; then
    echo "SKIPPED: $dir not found (set SHAPESPACE_DATA to the shared datasets folder)" >&2
    continue
  fi
  for f in "$dir"/*.obj "$dir"/*.off "$dir"/*.ply; do
    [ -e "$f" ] || continue
    name="$(basename "$dir")/$(basename "$f")"
    disk="$out/disk.obj"
    rm -f "$disk" "$out/r.json"
    if ! "$bin" prepare "$f" --out "$disk" >/dev/null 2>"$out/prep.txt"; then
      if ! "$bin" prepare "$f" --out "$disk" --seam "$seam" >/dev/null 2>"$out/prep.txt"; then
        echo "| $name | | prepare refused: $(tail -1 "$out/prep.txt" | cut -c1-160 | tr '|' ' ') | |"
        continue
      fi
      name="$name (seam $seam)"
    fi
    start=$(date +%s.%N)
    "$bin" conformal "$disk" --out "$out/c.obj" --report "$out/r.json" >/dev/null 2>"$out/c.txt"
    secs=$(echo "$(date +%s.%N) - $start" | bc)
    if [ ! -s "$out/r.json" ]; then
      echo "| $name | | refused: $(tail -1 "$out/c.txt" | sed 's/^shapespace: //' | cut -c1-200 | tr '|' ' ') | $(printf %.1f "$secs") |"
      continue
    fi
    python3 - "$out/r.json" "$name" "$secs" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
info = r["info"]
how = "BFF fallback" if info.get("bff_fallback") else r["method"].split(" ")[0]
region = info.get("region_repair")
if region:
    how += f", region repair ({region['vertices_moved']} moved)"
q = r["quality"]
if q["num_flipped"] + q.get("num_degenerate", 0):
    how += f", {q['num_flipped']} FLIPPED"
print(f"| {sys.argv[2]} | {r['num_vertices']} | {how} | {float(sys.argv[3]):.1f} |")
PY
  done
done
