"""Per-fold rows and dev / test means of diffusion_fold.py's JSON lines, one column group per model.

    python docs/experiments/scripts/fold_means.py docs/experiments/data/*.jsonl \\
        --model "imm-diffusion=final/diff-|diffusion-s0|imm-diffusion-seed0" --model "geometric=geometric/fold-" \\
        --where label_scale=2.5 --where sample_steps=10

A model is NAME=PATTERNS: rows whose checkpoint path contains one of the |-separated patterns. --where keeps rows whose
guidance has that value (GAN rows, without guidance, are kept). Where a checkpoint has several matching rows on a
fold, the last one counts; the checkpoints of one model on a fold (its seeds) are averaged, and the fold's row says how
many there are.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

DEV, TEST = ("s01", "s03", "s04"), ("s02", "s05", "s06", "s07")
COLUMNS = (("AFD", "afd", 3), ("AFD 1-NN", "afd_nn1", 3), ("best of 5", "afd_best_of_5", 3), ("FID", "fid", 2),
           ("FID 1-NN", "fid_nn1", 2), ("off-label", "off_label", 2), ("true label", "true_label", 2),
           ("mixed", "mix_mixed", 2), ("mixed, whole body", "mix_whole", 2), ("worst pair", "mix_worst_pair", 2),
           ("avoid lowers", "avoid_share_lowered", 2),
           ("limb speed", "interior_limb_speed_ratio", 2), ("lean deg", "lean_error_deg", 1),
           ("feet m/s", "foot_skate_mps", 3), ("bones cm", "bone_error_cm", 2),
           ("multimodality / real", "multimodality_ratio", 2),
           ("multimodality / real, one leader", "multimodality_same_leader_ratio", 2),
           ("smoothed / raw limb speed", "smooth_share", 2))


def rows_of(paths: list[Path], patterns: list[str], where: dict[str, float]) -> dict[str, dict]:
    """{fold: the mean over its checkpoints (seeds) of each figure, with "seeds": how many}."""
    runs = runs_of(paths, patterns, where)
    by_fold: dict[str, dict] = {}
    for fold, rows in runs.items():
        mean = {"seeds": len(rows)}
        for _, key, _ in COLUMNS:
            values = [r[key] for r in rows.values() if r.get(key) is not None]
            mean[key] = sum(values) / len(values) if len(values) == len(rows) else None
        by_fold[fold] = mean
    return by_fold


def read_rows(paths: list[Path]) -> list[dict]:
    """Every JSON line of the files, each with "file" (its file's stem) and, where its fold has one anywhere,
    "real_same_leader_diversity": the real followers' spread against one leader depends on the fold's data and judges
    alone, so rows scored before it was reported take it from any row of their fold."""
    rows = [json.loads(line) | {"file": path.stem} for path in paths for line in path.read_text().splitlines()]
    same_leader = {r["fold"]: r["real_same_leader_diversity"] for r in rows if r.get("real_same_leader_diversity")}
    for row in rows:
        if row["fold"] in same_leader:
            row.setdefault("real_same_leader_diversity", same_leader[row["fold"]])
    return rows


def runs_of(paths: list[Path], patterns: list[str], where: dict[str, float]) -> dict[str, dict[str, dict]]:
    from imm_model.families.diffusion.sampler import Guidance

    defaults = Guidance().to_dict()  # rows from before a guidance field existed sampled with its default
    by_fold: dict[str, dict[str, dict]] = {}
    for row in read_rows(paths):
        # rows of no checkpoint (memory_starts.py scores the reaction memory's starts alone) belong to no model
        if not any(p in row.get("checkpoint", "") for p in patterns):
            continue
        guidance = row.get("guidance")
        if guidance and any(float(guidance.get(k, defaults.get(k, float("nan")))) != v for k, v in where.items()):
            continue
        if row.get("multimodality") is not None:
            row["multimodality_ratio"] = row["multimodality"] / row["real_class_diversity"]
            if row.get("real_same_leader_diversity") is not None:
                row["multimodality_same_leader_ratio"] = row["multimodality"] / row["real_same_leader_diversity"]
        if row.get("smooth_limb_speed_ratio") is not None:  # 1: no jitter; lower: part of the motion is jitter
            row["smooth_share"] = row["smooth_limb_speed_ratio"] / row["limb_speed_ratio"]
        by_fold.setdefault(row["fold"], {})[row["checkpoint"]] = row
    return by_fold


def fmt(value, digits: int) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--model", action="append", required=True, help="NAME=PATTERN[|PATTERN...]")
    ap.add_argument("--where", action="append", default=[], help="guidance KEY=VALUE")
    args = ap.parse_args()
    where = {k: float(v) for k, v in (w.split("=", 1) for w in args.where)}
    models = {name: rows_of(args.files, patterns.split("|"), where)
              for name, patterns in (m.split("=", 1) for m in args.model)}
    print("| fold | model | " + " | ".join(c[0] for c in COLUMNS) + " |")
    print("|---|---|" + "---:|" * len(COLUMNS))
    for fold in (*DEV, *TEST):
        for name, rows in models.items():
            if fold in rows:
                seeds = rows[fold]["seeds"]
                cells = " | ".join(fmt(rows[fold].get(key), d) for _, key, d in COLUMNS)
                print(f"| {fold} | {name}{f' ({seeds} seeds)' if seeds > 1 else ''} | {cells} |")
    for group, folds in (("dev mean", DEV), ("test mean", TEST)):
        for name, rows in models.items():
            present = [rows[f] for f in folds if f in rows]
            if not present:
                continue
            cells = []
            for _, key, d in COLUMNS:
                values = [r[key] for r in present if r.get(key) is not None]
                cells.append(fmt(sum(values) / len(values), d) if len(values) == len(present) else "")
            print(f"| {group} ({len(present)} folds) | {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
