"""How far the studio's draft of a reaction lies from the reaction itself: the bundled student against the bundled
default on the held-out leaders, each under its own class and the same seed, beside the gap between two of the
default's seeds (the mean distance over joints and frames, in metres, per leader; median and p90 over leaders).

    python docs/experiments/scripts/draft_gap.py
"""

from __future__ import annotations

import numpy as np

from imm_model.data.dataset import InteractionDataset
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DATA, SAMPLE_DIFFUSION, SAMPLE_STUDENT


def gap(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b, axis=-1).mean())


def main() -> None:
    data = InteractionDataset.load(SAMPLE_DATA)
    model, draft = ReactionModel.load(SAMPLE_DIFFUSION), ReactionModel.load(SAMPLE_STUDENT)
    drafts, seeds = [], []
    leaders = np.flatnonzero(data.held_out)
    for i in leaders:
        leader = data.canonical(i)[0]
        label = np.eye(len(data.class_names), dtype=np.float32)[data.actions[i]]
        own = model.synthesize_canonical(leader, label, seed=0)
        drafts.append(gap(own, draft.synthesize_canonical(leader, label, seed=0)))
        seeds.append(gap(own, model.synthesize_canonical(leader, label, seed=1)))
    print(f"{len(leaders)} held-out leaders: draft to the default's own reaction, median {np.median(drafts):.3f} m, "
          f"p90 {np.percentile(drafts, 90):.3f} m; the default's seed 0 to seed 1, median {np.median(seeds):.3f} m")


if __name__ == "__main__":
    main()
