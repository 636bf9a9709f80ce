#!/usr/bin/env bash
# Test the Slurm scripts on a one-node Slurm started here: installs slurm-wlm and munge from the
# distribution's packages if missing (apt-get; needs root, or sudo), writes a one-node slurm.conf
# in a temporary directory, starts munged, slurmctld and slurmd itself (on ports of its own, so a
# Slurm already running is left alone), submits a small study as 3 shards and a merge with
# submit.sh, waits, and compares the merged sweep.csv and sweep.json with one local run's bytes.
# Stops the daemons it started on exit. Exit code 0 when the bytes match.
#
#   scripts/slurm/test-one-node.sh [PXPL5_BINARY]
#
# Opt-in: `PXPL5_SLURM_TEST=1 cargo test -p pxpl5-cli --test slurm` runs it (it takes about
# ten seconds once the packages are installed; installing them takes a minute or two more).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
PXPL5="$(realpath "${1:-${PXPL5:-$here/../../target/release/pxpl5}}")"
[ -x "$PXPL5" ] || { echo "$0: no pxpl5 binary at $PXPL5 (cargo build --release)" >&2; exit 2; }

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
        echo "$0: need root or sudo to run: $*" >&2; exit 2
    fi
}
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        slurm-wlm munge >/dev/null
fi

work="$(mktemp -d /tmp/pxpl5-slurm.XXXXXX)"
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
}
trap cleanup EXIT
mkdir -p "$work"/{state,spool,munge,study}
host="$(hostname -s)"
user="$(id -un)"

# munge: a key and a socket of our own.
key="$work/munge/munge.key"
dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
chmod 600 "$key"
socket="$work/munge/munge.socket"
munged --key-file="$key" --socket="$socket" --pid-file="$work/munge/munged.pid" \
    --log-file="$work/munge/munged.log" --seed-file="$work/munge/munged.seed" --force \
    --foreground >"$work/munge/munged.out" 2>&1 &
pids+=($!)

export SLURM_CONF="$work/slurm.conf"
cat > "$SLURM_CONF" <<CONF
ClusterName=pxpl5test
SlurmctldHost=$host
SlurmUser=$user
SlurmctldPort=16817
SlurmdPort=16818
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
NodeName=$host CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
sleep 1
slurmctld -D -i >"$work/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D >"$work/slurmd.out" 2>&1 &
pids+=($!)

# Wait for the node to take jobs.
for _ in $(seq 60); do
    state="$(sinfo -h -o %T 2>/dev/null || true)"
    [ "$state" = idle ] && break
    sleep 1
done
[ "$state" = idle ] || { echo "$0: the node did not come up (state: $state)" >&2;
    tail -20 "$work/slurmctld.log" "$work/slurmd.log" >&2; exit 1; }

study=(--set renderer.count=1,2 --set program.resolution=16,32 --set program.patch_size=400
    --shots 4)
merge="$(PXPL5="$PXPL5" "$here/submit.sh" "$work/study" 3 "${study[@]}")"
echo "submitted: 3 shards and merge job $merge"
for _ in $(seq 300); do
    left="$(squeue -h -j "$merge" -o %r 2>/dev/null || true)"
    # Done, or never to run (a shard failed, so its afterok dependency cannot be met).
    [ -z "$left" ] && break
    case "$left" in *DependencyNeverSatisfied*) scancel "$merge"; break ;; esac
    sleep 1
done
if [ ! -f "$work/study/merged/sweep.csv" ]; then
    echo "$0: the merge job left no output; logs:" >&2
    tail -n 20 "$work"/study/*.log "$work/slurmctld.log" >&2 || true
    exit 1
fi
"$PXPL5" -q sweep "${study[@]}" --out "$work/single" >/dev/null
for f in sweep.csv sweep.json; do
    cmp "$work/study/merged/$f" "$work/single/$f"
done
echo "ok: the Slurm array's merged sweep.csv and sweep.json equal one run's bytes ($work)"
