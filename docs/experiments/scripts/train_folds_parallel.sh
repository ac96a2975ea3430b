#!/usr/bin/env bash
# Train one recipe on every LOSO fold x seed as separate processes running side by side: on a GPU machine the
# small batches leave the card mostly idle, so 21 runs at once take little longer than one. Each run is
# `imm train` in a process session of its own (setsid), so it outlives the shell that started it; its output is
# OUT/seedN/fold-sXX/ and its log OUT/seedN-sXX.log.
#
#   docs/experiments/scripts/train_folds_parallel.sh CONFIG OUT "0 1 2" [imm train options, e.g. --device cuda]
#
# IMM (default `imm`) is the command that runs imm; wait with `docs/experiments/scripts/train_folds_parallel.sh --wait OUT N`
# (N runs expected), which prints how many runs have written final.safetensors, every 15 s, until all have.
set -euo pipefail
if [ "${1:-}" = "--wait" ]; then
  out=$2; expected=$3
  while true; do
    done_runs=$(find "$out" -name final.safetensors | wc -l)
    echo "[$(date +%T)] $done_runs/$expected runs finished"
    [ "$done_runs" -ge "$expected" ] && exit 0
    sleep 15
  done
fi
config=$1; out=$2; seeds=$3; shift 3
IMM=${IMM:-imm}
mkdir -p "$out"
for seed in $seeds; do
  for fold in s01 s02 s03 s04 s05 s06 s07; do
    setsid bash -c "$IMM train --config $config --fold $fold --seed $seed --threads 1 --quiet --out $out/seed$seed $* \
      > $out/seed$seed-$fold.log 2>&1" < /dev/null &
  done
done
echo "started $(( $(echo "$seeds" | wc -w) * 7 )) runs of $config in $out"
