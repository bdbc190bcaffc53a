#!/usr/bin/env bash
# Area-preserving maps of every TOSCA mesh in DIR (default: tosca/ of the shared datasets folder,
# $SHAPESPACE_DATA, else ../shared/datasets beside the repository), made
# disks by `shapespace prepare` with and without `--seam 1`. Prints one Markdown row per mesh and
# cut: OT outcome, steps, seconds (conformal / OT / repair / total), median |Υ| of the
# conformal and of the area-preserving map, and whether the conformal map fell back to BFF.
# Usage: scripts/tosca_seam_sweep.sh [DIR] [SEAM...]   (needs `cargo build --release` first;
# the binary is taken from $CARGO_TARGET_DIR, default target/)
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
data=${SHAPESPACE_DATA:-$root/../shared/datasets}
dir=${1:-$data/tosca}
shift || true
seams=${*:-"0 1"}
bin=${CARGO_TARGET_DIR:-$root/target}/release/shapespace
if [ ! -d "$dir" ]; then
  echo "SKIPPED: $dir not found (give DIR or set SHAPESPACE_DATA to the shared datasets folder)" >&2
  exit 1
fi
if [ ! -x "$bin" ]; then
  echo "$bin not found: run cargo build --release first" >&2
  exit 2
fi
out=$(mktemp -d)
echo "| mesh | seam | V | OT | steps | conformal s | OT s | repair s | total s | conformal median abs(Υ) | area-preserving median abs(Υ) | BFF fallback |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for f in "$dir"/*.off; do
  name=$(basename "$f" .off)
  for k in $seams; do
    disk="$out/${name}_$k.obj"
    if ! "$bin" prepare "$f" --out "$disk" --seam "$k" 2>"$out/prep.txt"; then
      echo "| $name | $k | | prepare failed: $(tail -c 200 "$out/prep.txt" | tr '\n|' '  ') |"
      continue
    fi
    "$bin" param "$disk" --out "$out/ap.obj" --report "$out/r.json" >/dev/null 2>"$out/param.txt"
    if [ ! -s "$out/r.json" ]; then
      echo "| $name | $k | | failed: $(grep -v '^\s*$' "$out/param.txt" | tail -1 | cut -c1-160 | tr '|' ' ') |"
      continue
    fi
    python3 - "$out/r.json" "$name" "$k" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
ot, t, d = r["ot"], r["timings"], r["distortion"]["maps"]
fb = r.get("conformal_bff_fallback")
print(f"| {sys.argv[2]} | {sys.argv[3]} | {r['num_vertices']} | {'converged' if ot['converged'] else ot['stop']} | {ot['iterations']} | "
      f"{t['conformal']:.2f} | {t['ot']:.2f} | {t['repair']:.2f} | {t['total']:.2f} | "
      f"{d[0]['abs_area_distortion']['median']:.3f} | {d[1]['abs_area_distortion']['median']:.3f} | "
      f"{'after ' + str(fb['green_folds']) + ' folds' if fb else ''} |")
PY
    rm -f "$out/r.json"
  done
done
rm -rf "$out"
