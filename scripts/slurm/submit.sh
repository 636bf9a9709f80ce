#!/usr/bin/env bash
# Submit a `pxpl5 sweep` study to Slurm as a job array of SHARDS shards and a merge job that runs
# once every shard has succeeded; prints the merge job's id. The merged study is OUT/merged.
#
#   scripts/slurm/submit.sh OUT SHARDS [pxpl5 sweep flags...]
#   e.g. scripts/slurm/submit.sh /scratch/study 8 --set renderer.count=1,4,16 \
#            --set program.resolution=32,64,128
#
# PXPL5 names the binary (default: pxpl5 on PATH); it and OUT must be on a file system every
# node sees. Extra sbatch options (partition, time) go in SBATCH_* environment variables.
set -euo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 OUT SHARDS [pxpl5 sweep flags...]" >&2
    exit 2
fi
OUT="$1"
SHARDS="$2"
shift 2
case "$SHARDS" in '' | *[!0-9]* | 0) echo "$0: SHARDS must be a number above 0" >&2; exit 2 ;; esac
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$OUT"
export OUT SHARDS PXPL5="${PXPL5:-pxpl5}" SWEEP_ARGS="$*"
array=$(sbatch --parsable --chdir="$OUT" --array="0-$((SHARDS - 1))" --export=ALL \
    "$here/sweep.sbatch")
array="${array%%;*}"
merge=$(sbatch --parsable --chdir="$OUT" --dependency="afterok:$array" --export=ALL \
    "$here/merge.sbatch")
echo "${merge%%;*}"
