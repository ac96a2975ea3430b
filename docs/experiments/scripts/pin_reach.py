"""How far a planted foot may lag the network's foot in the live clean-up (cleanup.py PIN_REACH_M): the bundled live
reactor's reaction to each held-out s04 leader (its true class, seed 0), cleaned with each reach, and the foot skate
(plausibility.py `foot_skate_mps`) and the largest joint step from one frame to the next, averaged over leaders.

    OMP_NUM_THREADS=1 python docs/experiments/scripts/pin_reach.py --reach inf 0.3 0.15

Record: docs/experiments/causal-reactor.md ("Continuous takes and a leader who walks").
"""

from __future__ import annotations

import argparse

import numpy as np
from long_takes import online_follower

from imm_model import cleanup, paths
from imm_model.data.bundle import load_any
from imm_model.data.splits import loso_fold
from imm_model.evaluation.plausibility import foot_skate_mps, frame_rate
from imm_model.families.base import ReactionModel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", default=str(paths.SAMPLE_DIFFUSION))
    ap.add_argument("--reach", type=float, nargs="+", default=[float("inf"), 0.3, 0.15])
    args = ap.parse_args()
    data = load_any(paths.SAMPLE_DATA)
    model = ReactionModel.load(args.checkpoint)
    fps = frame_rate(data.dataset)
    held_out = loso_fold(data.subject_pairs, model.held_out_subject).test
    for reach in args.reach:
        cleanup.PIN_REACH_M = reach
        skate, steps = [], []
        for i in held_out:
            follower = online_follower(model, data.world(int(i))[0], {data.class_names[data.actions[i]]: 1.0}, 0)[0]
            skate.append(foot_skate_mps(follower, model.skeleton, fps))
            steps.append(np.linalg.norm(np.diff(follower, axis=0), axis=-1).max())
        print(f"reach {reach} m: foot skate {np.mean(skate):.4f} m/s, largest joint step {np.mean(steps):.3f} m "
              f"({len(held_out)} leaders of {model.held_out_subject})")


if __name__ == "__main__":
    main()
