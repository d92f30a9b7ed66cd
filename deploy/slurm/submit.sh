#!/usr/bin/env bash
# Submit a whole piece of work as Slurm jobs chained with --dependency=afterok:
#
#   deploy/slurm/submit.sh datagen TASK DEMOS OUT [SHARDS]      array, then merge
#   deploy/slurm/submit.sh models TASK DEMOS WORK [SHARDS]      array, merge, then train into
#                                                               WORK/models/TASK
#   deploy/slurm/submit.sh eval TASK FIRST_SEED OUT [SHARDS]    array, then merge
#
# SHARDS defaults to 4. Extra flags for the commands: DATAGEN_ARGS, EVAL_ARGS, METHODS, TRIALS
# in the environment. Run from the repository root after `cargo build --release`; prints the
# job ids. SBATCH_ARGS (e.g. "--partition=cpu --account=lab") is passed to every sbatch.
set -euo pipefail
cd "$(dirname "$0")/../.."
here=deploy/slurm
usage() { sed -n '2,12p' "$0" >&2; exit 2; }
[ $# -ge 4 ] || usage
what=$1 task=$2 arg=$3 out=$4 shards=${5:-4}
case "$task" in screwdriver|card) ;; *) echo "TASK must be screwdriver or card, not '$task'" >&2; exit 2 ;; esac
[[ "$shards" =~ ^[1-9][0-9]*$ ]] || { echo "SHARDS must be a positive whole number, not '$shards'" >&2; exit 2; }
[ -x target/release/dips ] || { echo "build first: cargo build --release" >&2; exit 2; }
out=$(realpath -m "$out")
mkdir -p "$out"
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of flags
sb() { sbatch --parsable ${SBATCH_ARGS:-} "$@"; }
case "$what" in
    datagen|models)
        data=$out
        [ "$what" = models ] && data=$out/data/$task
        array=$(sb --array=0-$((shards - 1)) --export=ALL,TASK="$task",DEMOS="$arg",OUT="$data" \
            "$here/datagen.sbatch")
        merge=$(sb --dependency=afterok:"$array" --export=ALL,TASK="$task",OUT="$data" \
            "$here/merge-datagen.sbatch")
        echo "datagen array $array, merge $merge ($data)"
        if [ "$what" = models ]; then
            train=$(sb --dependency=afterok:"$merge" \
                --export=ALL,TASK="$task",DATA="$data",MODELS="$out/models/$task" "$here/train.sbatch")
            echo "train $train ($out/models/$task)"
        fi
        ;;
    eval)
        array=$(sb --array=0-$((shards - 1)) --export=ALL,TASK="$task",FIRST_SEED="$arg",OUT="$out" \
            "$here/eval.sbatch")
        merge=$(sb --dependency=afterok:"$array" --export=ALL,OUT="$out" "$here/merge-eval.sbatch")
        echo "eval array $array, merge $merge ($out)"
        ;;
    *) usage ;;
esac
