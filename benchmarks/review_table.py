"""Time of the studio's review across sequences (imm_model/evaluation/review.py) on the bundled held-out split (fold
s04), for the bundled GAN and diffusion models, on one thread:

    OMP_NUM_THREADS=1 python benchmarks/review_table.py [--repeats 3] [--chunk 1 4 64]

Prints the classifiers' load (the interaction classifier is trained and cached on first use, which this does not time)
and, per model, the table's wall time (best and median of the repeats; one batched synthesis each) and its rows.
"""

from __future__ import annotations

import argparse
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--chunk", type=int, nargs="*", default=[],
                    help="also time the diffusion table with these rows per sampler call (review.CPU_SAMPLER_CHUNK)")
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    from imm_model.data.dataset import InteractionDataset
    from imm_model.evaluation import review
    from imm_model.evaluation.review import ReviewThresholds, fold_interaction_features, real_foot_threshold, review_table
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_CHECKPOINT, SAMPLE_DATA, SAMPLE_DIFFUSION, SAMPLE_JUDGE
    from imm_model.reads_as import ReadsAs

    DEFAULT_CHUNK = review.CPU_SAMPLER_CHUNK
    data = InteractionDataset.load(SAMPLE_DATA)
    t0 = time.perf_counter()
    judge = ReadsAs.load(SAMPLE_JUDGE)
    features = fold_interaction_features(data, "s04", progress=True)
    t1 = time.perf_counter()
    thresholds = ReviewThresholds(real_foot_threshold(data))
    t2 = time.perf_counter()
    print(f"judge + interaction classifier loaded in {t1 - t0:.2f} s; foot threshold "
          f"{thresholds.foot_skate_mps:.3f} m/s from the real followers in {t2 - t1:.2f} s")
    runs = [("gan", SAMPLE_CHECKPOINT, None), ("diffusion", SAMPLE_DIFFUSION, None)]
    runs += [(f"diffusion, {c} rows per call", SAMPLE_DIFFUSION, c) for c in args.chunk]
    for name, path, chunk in runs:
        model = ReactionModel.load(path)
        review.CPU_SAMPLER_CHUNK = chunk or DEFAULT_CHUNK
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            rows = review_table(model, data, judge=judge, features=features, thresholds=thresholds)
            times.append(time.perf_counter() - start)
        flagged = sum(r.contact_flag or r.foot_flag for r in rows)
        print(f"{name}: {len(rows)} rows in {min(times):.2f} s best, {statistics.median(times):.2f} s median of "
              f"{args.repeats} (mean AFD {sum(r.afd for r in rows) / len(rows):.3f}, {flagged} rows flagged)")


if __name__ == "__main__":
    main()
