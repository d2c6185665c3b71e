#!/bin/bash
# Submits a noisefree job folder to Slurm: the job array of render.sbatch (every task, or only
# the tasks given, e.g. those a failed merge names) and merge.sbatch, which waits for it.
#
#     submit.sh            # every task
#     submit.sh 2 5        # tasks 2 and 5 only, then the merge again
#
# Prints the job ids. sbatch's environment (SBATCH_PARTITION, SBATCH_GRES, SBATCH_HOLD, ...)
# applies to both jobs.
set -euo pipefail
cd "$(dirname "$0")"
source ./job.env
if (($#)); then
    array=$(IFS=,; echo "$*")
else
    array=0-$((RENDERS * TASKS - 1))
fi
mkdir -p logs
render=$(sbatch --parsable --array="$array" render.sbatch)
render=${render%%;*}
merge=$(sbatch --parsable --dependency="afterany:$render" merge.sbatch)
merge=${merge%%;*}
echo "submitted job array $render (tasks $array) and merge job $merge in $PWD"
