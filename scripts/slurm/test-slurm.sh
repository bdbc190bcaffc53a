#!/usr/bin/env bash
# End-to-end test of the Slurm scripts: a single-node Slurm (Debian's slurm-wlm and munge,
# installed with apt-get when missing and this runs as root) runs submit.sh's array of 3 shards
# (at most 2 at once) and the dependent merge job over 4 bundled faces; the merged files must
# equal a single run's (distances.csv byte for byte, pairs.csv but the seconds and their
# check, report.json but the timings and the output paths). Where Slurm cannot be installed or
# started, it says so loudly and runs the same two job scripts by hand with the array
# variables set (exit code 0 then too, after the comparison). The daemons it started are
# stopped by their pid files at the end.
#
#   scripts/slurm/test-slurm.sh        (binary: $SHAPESPACE_BIN, else the release build)
#   SHAPESPACE_TEST_NO_SLURM=1 scripts/slurm/test-slurm.sh   (the fallback, by hand)
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
here="$repo/scripts/slurm"
binary="${SHAPESPACE_BIN:-${CARGO_TARGET_DIR:-$repo/target}/release/shapespace}"
[ -x "$binary" ] || { echo "test-slurm: no binary at $binary (cargo build --release -p shapespace-cli)" >&2; exit 2; }
tmp="$(mktemp -d)"
pids=()
cleanup() {
    local stopped=()
    for pidfile in "${pids[@]}"; do
        if [ -f "$pidfile" ]; then
            stopped+=("$(cat "$pidfile")")
            kill "${stopped[-1]}" 2>/dev/null || true
        fi
    done
    # (slurmctld saves its state as it stops: wait for them before removing their folder)
    for pid in "${stopped[@]}"; do
        for _ in $(seq 1 50); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.2
        done
    done
    if grep -qs "written by test-slurm" /etc/slurm/slurm.conf; then rm -f /etc/slurm/slurm.conf; fi
    rm -rf "$tmp"
}
trap cleanup EXIT
for f in id00_happy id00_neutral id01_sad id02_happy; do
    echo "$repo/datasets/faces/$f.obj"
done > "$tmp/files.txt"
mapfile -t files < "$tmp/files.txt"
mkdir -p "$tmp/single"
"$binary" distances "${files[@]}" --out "$tmp/single/out" --quiet --threads 1 2>/dev/null

loud() {
    echo "######################################################################" >&2
    echo "# test-slurm: $*" >&2
    echo "######################################################################" >&2
}

start_slurm() {
    [ -z "${SHAPESPACE_TEST_NO_SLURM:-}" ] || { echo "SHAPESPACE_TEST_NO_SLURM is set"; return 1; }
    [ "$(id -u)" -eq 0 ] || { echo "not root"; return 1; }
    if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
        command -v apt-get >/dev/null || { echo "no apt-get"; return 1; }
        (apt-get install -y -qq slurm-wlm munge >/dev/null 2>&1 \
            || { apt-get update -qq >/dev/null 2>&1 && apt-get install -y -qq slurm-wlm munge >/dev/null 2>&1; }) \
            || { echo "apt-get install slurm-wlm munge failed"; return 1; }
    fi
    local host
    host="$(hostname -s)"
    mkdir -p /etc/munge /run/munge "$tmp/slurm/state" "$tmp/slurm/spool" /etc/slurm
    if [ ! -s /etc/munge/munge.key ]; then
        head -c 1024 /dev/urandom > /etc/munge/munge.key
    fi
    chown munge:munge /etc/munge/munge.key /run/munge
    chmod 400 /etc/munge/munge.key
    if ! pgrep -u munge munged >/dev/null; then
        su -s /bin/sh munge -c "munged --pid-file=/run/munge/test-slurm.pid" || return 1
        pids+=(/run/munge/test-slurm.pid)
    fi
    local conf=/etc/slurm/slurm.conf
    if [ -e "$conf" ] && ! grep -q "written by test-slurm" "$conf"; then
        echo "an existing $conf (not this test's)"
        return 1
    fi
    cat > "$conf" <<CONF
# written by test-slurm.sh
ClusterName=test
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$tmp/slurm/state
SlurmdSpoolDir=$tmp/slurm/spool
SlurmctldPidFile=$tmp/slurm/slurmctld.pid
SlurmdPidFile=$tmp/slurm/slurmd.pid
SlurmctldLogFile=$tmp/slurm/slurmctld.log
SlurmdLogFile=$tmp/slurm/slurmd.log
NodeName=$host CPUs=2 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    slurmctld || return 1
    pids+=("$tmp/slurm/slurmctld.pid")
    slurmd || return 1
    pids+=("$tmp/slurm/slurmd.pid")
    for _ in $(seq 1 30); do
        sinfo -h -o %T 2>/dev/null | grep -qE "idle|mix" && return 0
        sleep 1
    done
    echo "the node did not become idle"
    return 1
}

out="$tmp/run"
# (not in a subshell: the pid files it starts go to `pids` for the cleanup)
if start_slurm > "$tmp/start.log" 2>&1; then
    echo "test-slurm: single-node Slurm started ($(sinfo -V))"
    # shellcheck disable=SC2046
    set -- $(SHAPESPACE="$binary" "$here/submit.sh" "$tmp/files.txt" "$out" 3 2)
    echo "test-slurm: submitted array $2, merge $4"
    for _ in $(seq 1 300); do
        squeue -h -j "$2,$4" 2>/dev/null | grep -q . || break
        sleep 1
    done
    if squeue -h -j "$2,$4" 2>/dev/null | grep -q .; then
        echo "test-slurm: jobs still queued after 300 s:" >&2
        squeue >&2
        exit 1
    fi
    ls "$out"/*.log >/dev/null
    mode=slurm
else
    loud "SLURM NOT AVAILABLE ($(tail -1 "$tmp/start.log")): running the job scripts by hand with SLURM_ARRAY_TASK_ID set"
    mkdir -p "$out"
    for k in 1 2 3; do
        SLURM_ARRAY_TASK_ID=$k SHAPESPACE="$binary" SHAPESPACE_FILES="$tmp/files.txt" SHAPESPACE_OUT="$out" \
            SHAPESPACE_SHARDS=3 "$here/shard.sbatch" 2>/dev/null
    done
    SHAPESPACE="$binary" SHAPESPACE_OUT="$out" SHAPESPACE_SHARDS=3 "$here/merge.sbatch"
    mode=by-hand
fi
[ -f "$out/merged/report.json" ] || { echo "test-slurm: no merged output in $out/merged" >&2; cat "$out"/*.log >&2 || true; exit 1; }
cmp "$tmp/single/out/distances.csv" "$out/merged/distances.csv"
python3 - "$tmp/single/out" "$out/merged" <<'PY'
import json, sys
a, b = sys.argv[1:]
def pairs(d):
    rows = [line.split(",") for line in open(f"{d}/pairs.csv").read().splitlines()]
    return [r[:6] + r[7:10] for r in rows]
def report(d):
    r = json.load(open(f"{d}/report.json"))
    for key in ("timings", "files"):
        r.pop(key)
    for i in r["inputs"]:
        i.pop("seconds")
    return r
assert pairs(a) == pairs(b), "pairs.csv differs"
assert len(pairs(a)) == 7, len(pairs(a))
assert report(a) == report(b), "report.json differs"
PY
echo "test-slurm: ok ($mode): 3 shards and their merge equal a single run"
