#!/bin/bash
# The files `imm generate` writes for a fixed set of commands, to compare two trees byte for byte:
#   docs/experiments/scripts/generate_outputs.sh OLD_TREE /tmp/before
#   docs/experiments/scripts/generate_outputs.sh NEW_TREE /tmp/after
#   diff -rq /tmp/before /tmp/after
# Each tree's code runs with this checkout's Python environment (.venv beside this script's checkout, or $PY).
tree=$(cd "$1" && pwd); out=$2
PY=${PY:-$(cd "$(dirname "$0")/../../.." && pwd)/.venv/bin/python}
cd "$tree" || exit 2
export PYTHONPATH=$tree OMP_NUM_THREADS=1
mkdir -p "$out"
run() { "$PY" -m imm_model.cli generate "$@" 2>&1 | grep -v "item/s" | tail -1; }
run --leader tests/fixtures/bvh/cmu_01_01.bvh --label shaking_hands=1 --out "$out/a.bvh"
run --leader tests/fixtures/bvh/cmu_02_03_daz.bvh --label kicking=1,hugging=0.5 --out "$out/b.npz"
run --sequences held-out --grid --out "$out/grid"
run --sequences held-out --label pushing=-1 --format bvh --out "$out/gridbvh"
run --leader tests/fixtures/bvh/cmu_01_01.bvh --checkpoint sample_data/imm_diffusion.safetensors --samples 3 --label punching=1 --out "$out/diff"
run --sequences held-out --checkpoint sample_data/imm_diffusion.safetensors --label hugging=1 --seed 4 --out "$out/diffb"
run --sequence s01s02/03/001 --checkpoint sample_data/imm_diffusion.safetensors --memory 0.5 --label pushing=1 --out "$out/mem.npz"
echo "$(find "$out" -type f | wc -l) files in $out"
