"""The distilled student against its teacher, fold by fold: the rows diffusion_fold.py wrote for each fold's student,
beside the teacher's at its shipped 7 steps and at 2 (sampler-steps.jsonl), its part table with the parts' reactions
joined (part-folds.jsonl, seed 0), as a table per group (dev s01 s03 s04, test s02 s05 s06 s07) with each one's
difference from the teacher at 7 steps paired by fold and a 95 % Student t interval over the folds.

    python docs/experiments/scripts/diffusion_fold.py --checkpoint runs/imm-diffusion-student/fold-sXX/final.safetensors \\
        --fold sXX --out docs/experiments/data/sampler-student.jsonl     # per fold
    python docs/experiments/scripts/sampler_student.py

With data/sampler-student-label.jsonl (the same per fold for the student trained with the label critic) its column
joins the table; `--column NAME=PATH` adds another student's rows (e.g. the window-taught student's,
data/sampler-student-windows.jsonl). KID and jitter are read where the rows have them: the teacher's from
data/teacher-fold-figures.jsonl (diffusion_fold.py on each fold's teacher at its shipped 7 steps).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from sampler_steps import FIGURES, GROUPS, interval

DATA = Path(__file__).resolve().parents[1] / "data"
JOINED = ("part_read",)  # the teacher's figures read from its joined-part rows (part-folds.jsonl)
LATER = ("kid", "jitter_ratio")  # figures diffusion_fold.py records since the first student rows; the teacher's below


def rows(path: Path) -> list[dict]:
    return [json.loads(line) for line in open(path)] if path.exists() else []


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--student", type=Path, default=DATA / "sampler-student.jsonl")
    ap.add_argument("--steps", type=Path, default=DATA / "sampler-steps.jsonl")
    ap.add_argument("--parts", type=Path, default=DATA / "part-folds.jsonl")
    ap.add_argument("--labelled", type=Path, default=DATA / "sampler-student-label.jsonl",
                    help="rows of the student trained with the label critic (imm-diffusion-student now), a column when present")
    ap.add_argument("--teacher-figures", type=Path, default=DATA / "teacher-fold-figures.jsonl",
                    help="the teacher's rows at 7 steps with the later figures (KID, jitter)")
    ap.add_argument("--column", action="append", default=[], metavar="NAME=PATH",
                    help="another student's rows (diffusion_fold.py per fold) as a column named NAME")
    args = ap.parse_args()
    teacher = {(r["fold"], r["guidance"]["sample_steps"]): r for r in rows(args.steps)}
    joined = {r["fold"]: r for r in rows(args.parts) if r.get("join_outputs") and r["seed"] == 0 and "parts" not in r["checkpoint"]}
    later = {r["fold"]: {k: r[k] for k in LATER if k in r} for r in rows(args.teacher_figures)}
    columns = {"teacher, 7 steps": {f: teacher[(f, 7)] | {k: joined[f][k] for k in JOINED if f in joined} | later.get(f, {})
                                    for f, s in teacher if s == 7},
               "teacher, 2 steps": {f: r for (f, s), r in teacher.items() if s == 2},
               "student, 2 steps": {r["fold"]: r for r in rows(args.student)}}
    if rows(args.labelled):
        columns["student + label critic"] = {r["fold"]: r for r in rows(args.labelled)}
    for column in args.column:
        name, _, path = column.partition("=")
        columns[name] = {r["fold"]: r for r in rows(Path(path))}
    names = list(columns)
    for group, folds in GROUPS.items():
        have = [f for f in folds if all(f in columns[n] for n in names)]
        print(f"\n{group} folds {' '.join(have)} (of {' '.join(folds)})")
        if not have:
            continue
        print("| figure | " + " | ".join(names) + " | " + " | ".join(f"{n} - teacher, 7 [95 % t]" for n in names[1:]) + " |")
        print("|---|" + "---:|" * (2 * len(names) - 1))
        for key in FIGURES + LATER:
            values = {n: np.array([columns[n][f].get(key, np.nan) for f in have], float) for n in names}
            cells = [f"{values[n].mean():.3f}" if np.isfinite(values[n]).all() else "-" for n in names]
            diffs = []
            for n in names[1:]:
                d = values[n] - values[names[0]]
                if not np.isfinite(d).all():
                    diffs.append("-")
                    continue
                lo, hi = interval(d)
                apart = "" if np.isnan(lo) or lo <= 0 <= hi else " *"
                diffs.append(f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]{apart}")
            print(f"| {key} | " + " | ".join(cells) + " | " + " | ".join(diffs) + " |")
    print("\n* the interval leaves out 0: a difference beyond the folds' spread. The teacher's part_read at 7 steps: its"
          " parts' reactions joined (part-folds.jsonl, seed 0); at 2 steps: joined at every step (sampler-steps.jsonl)")


if __name__ == "__main__":
    main()
