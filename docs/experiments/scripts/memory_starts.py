"""Score the reaction memory's starting reactions themselves, without the network: how the judges read what the
sampler starts from (real followers of the fold's training subjects, mixed as the signed label says), for the asked-for
class, the two-class mixes and avoid. One JSON line per fold.

    python docs/experiments/scripts/memory_starts.py --fold s04 --seeds 0 1 --out results.jsonl
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


class MemoryStarts:
    """The memory's start for each leader and label, drawn with one seed: a stand-in model for label_control."""

    def __init__(self, memory, seed: int):
        self.memory, self.seed = memory, seed

    def synthesize_batch_canonical(self, leaders, labels, seeds=None):
        return [self.memory.start(a, w, self.seed) for a, w in zip(leaders, labels, strict=True)]


def main() -> None:
    from diffusion_fold import record

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import loso_fold
    from imm_model.evaluation.loso import EvalOptions, FoldJudges, label_control
    from imm_model.families.diffusion.reaction_memory import ReactionMemory
    from imm_model.paths import SAMPLE_DATA

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fold", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--out", type=Path, default=None, help="append one JSON line per fold and seed here")
    args = ap.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    judges = FoldJudges(data, args.fold, EvalOptions(progress=False))
    memory = ReactionMemory.from_dataset(data, loso_fold(data.subject_pairs, args.fold).train)
    for seed in args.seeds:
        result = label_control(MemoryStarts(memory, seed), data, judges)
        matrix = np.array(result["adherence_matrix_judge"], dtype=float)
        record({"fold": args.fold, "seed": seed, "what": "memory starts",
                "off_label": result["adherence_off_diagonal_judge"], "true_label": float(np.nanmean(np.diag(matrix))),
                "mix_whole": float(np.mean([r["whole"] for r in result["mix_parts"]])),
                "mix_parts": float(np.mean([r["parts"] for r in result["mix_parts"]])),
                "mix_mixed": float(np.mean([r["mixed"] for r in result["mix_parts"]])),
                "avoid_share_lowered": result["avoid_judge"]["share_lowered"]}, args.out)


if __name__ == "__main__":
    main()
