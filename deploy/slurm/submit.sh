#!/bin/bash
# Submits a render as a Slurm job array of N parts and the stitch that
# joins them once all have succeeded; prints the two job ids (render, stitch)
# on standard output.
#
#   deploy/slurm/submit.sh SCENE OUT N [glint render options]
#
# ARRAY=3,7 submits only those parts (with a new stitch): after a task
# failed or was cancelled, `glint stitch OUT --parts N` names the missing
# indices. Resubmitting all of them is safe too: finished parts are kept.
# Extra sbatch options (partition, account, time) go in SBATCH_* variables
# or SBATCH_ARGS, e.g. SBATCH_ARGS="--partition=gpu --gres=gpu:1".
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 SCENE OUT N [glint render options]" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
scene=$1 out=$2 parts=$3
shift 3
array=${ARRAY:-0-$((parts - 1))}
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of options
render=$(sbatch --parsable ${SBATCH_ARGS:-} --array="$array" \
    "$here/render-part.sbatch" "$scene" "$out" "$parts" "$@")
render=${render%%;*}
# shellcheck disable=SC2086
stitch=$(sbatch --parsable ${SBATCH_ARGS:-} --dependency="afterok:$render" --kill-on-invalid-dep=yes \
    "$here/stitch.sbatch" "$out" "$parts")
stitch=${stitch%%;*}
echo "render array job $render (parts $array of $parts), stitch job $stitch" >&2
echo "$render $stitch"
