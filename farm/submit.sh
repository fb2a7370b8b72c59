#!/usr/bin/env bash
# Submit a wavetrace farm render to Slurm: a job array of N shards and a
# merge job that runs when all of them succeeded (--dependency=afterok).
#
#   farm/submit.sh [OPTIONS] [--] [RENDER_ARGS...]
#
# Options:
#   -n, --shards N        number of shards, the array's size (default 4)
#   -d, --parts DIR       directory for the partial files and logs, on storage
#                         that every node sees (default ./wavetrace-parts)
#   -o, --out FILE        the merged image: .png, .exr, .pfm or .wtacc
#                         (default ./render.png)
#   -p, --partial FILE    also write the merged partial file (.wtacc)
#   -a, --array LIST      submit only these shard indices, e.g. 3 or 1,5-7:
#                         rerun failed tasks, then merge again
#   -c, --cpus N          CPUs, and so threads, per shard (default 1)
#   -b, --wavetrace BIN   the wavetrace binary (default: wavetrace on PATH)
#   -h, --help            this text
# RENDER_ARGS go to every shard's `wavetrace render` (scene file, --spp,
# --width, --height, --seed, --profile, ...): give the same ones on a rerun.
# Other sbatch options come from sbatch's environment variables, e.g.
# SBATCH_PARTITION, SBATCH_ACCOUNT, SBATCH_TIMELIMIT.
#
# Prints the two job IDs as `array <ID>` and `merge <ID>`. Example:
#   farm/submit.sh -n 16 -c 8 -o figure8.exr -- --profile seed-figure8
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
shards=4 parts=./wavetrace-parts out=./render.png partial= array= cpus=1
bin=${WAVETRACE:-wavetrace}
usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
    case $1 in
    -n | --shards) shards=$2; shift 2 ;;
    -d | --parts) parts=$2; shift 2 ;;
    -o | --out) out=$2; shift 2 ;;
    -p | --partial) partial=$2; shift 2 ;;
    -a | --array) array=$2; shift 2 ;;
    -c | --cpus) cpus=$2; shift 2 ;;
    -b | --wavetrace) bin=$2; shift 2 ;;
    -h | --help) usage; exit 0 ;;
    --) shift; break ;;
    *) break ;;
    esac
done
case $shards in '' | *[!0-9]* | 0) echo "submit.sh: --shards must be a positive integer" >&2; exit 2 ;; esac
# Jobs may start in another directory: make every path absolute.
bin=$(command -v "$bin") || { echo "submit.sh: no wavetrace binary: $bin (use --wavetrace BIN)" >&2; exit 2; }
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
mkdir -p "$parts" "$(dirname "$out")"
parts=$(cd "$parts" && pwd)
out=$(cd "$(dirname "$out")" && pwd)/$(basename "$out")
merge_args=()
if [ -n "$partial" ]; then
    mkdir -p "$(dirname "$partial")"
    merge_args=(--partial "$(cd "$(dirname "$partial")" && pwd)/$(basename "$partial")")
fi
# Check the render arguments here, before anything is queued: a mistake
# fails now, not in N tasks later.
"$bin" render "$@" --shard "0/$shards" --partial "$parts/part-0.wtacc" --check >/dev/null ||
    { echo "submit.sh: nothing submitted" >&2; exit 2; }
export WAVETRACE=$bin
array_job=$(sbatch --parsable --array="${array:-0-$((shards - 1))}" \
    --cpus-per-task="$cpus" --output="$parts/shard-%a.log" \
    "$here/shard.sbatch" "$shards" "$parts" "$@")
array_job=${array_job%%;*}
merge_job=$(sbatch --parsable --dependency="afterok:$array_job" --kill-on-invalid-dep=yes \
    --output="$parts/merge.log" \
    "$here/merge.sbatch" "$shards" "$parts" "$out" "${merge_args[@]}")
merge_job=${merge_job%%;*}
echo "array $array_job"
echo "merge $merge_job"
