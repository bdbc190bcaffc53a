#!/usr/bin/env bash
# Submits a pairwise run to Slurm: an array of N shards, at most M running at once, and a merge
# job that runs when all shards have succeeded.
#
#   scripts/slurm/submit.sh FILES.txt OUT_DIR N [M] [-- extra sbatch options]
#
# FILES.txt: one mesh path per line (paths every node can read); OUT_DIR: a shared folder.
# Environment: SHAPESPACE (the binary, default `shapespace` on the PATH), SHAPESPACE_ARGS
# (more `distances` flags, e.g. "--symmetrize"), SHAPESPACE_CPUS (cores per shard, default 1).
# Prints the two job ids.
set -euo pipefail
if [ $# -lt 3 ]; then
    sed -n '2,12p' "$0" >&2
    exit 2
fi
files="$(realpath "$1")" out="$2" shards="$3" throttle="${4:-$3}"
shift $(( $# >= 4 ? 4 : 3 ))
[ "${1:-}" = "--" ] && shift
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$out"
out="$(realpath "$out")"
export SHAPESPACE_FILES="$files" SHAPESPACE_OUT="$out" SHAPESPACE_SHARDS="$shards"
export SHAPESPACE="${SHAPESPACE:-$(command -v shapespace)}"
array=$(sbatch --parsable --export=ALL --chdir="$out" --cpus-per-task="${SHAPESPACE_CPUS:-1}" \
    --array="1-$shards%$throttle" "$@" "$here/shard.sbatch")
array="${array%%;*}"
merge=$(sbatch --parsable --export=ALL --chdir="$out" --dependency="afterok:$array" "$@" "$here/merge.sbatch")
echo "array $array merge ${merge%%;*}"
