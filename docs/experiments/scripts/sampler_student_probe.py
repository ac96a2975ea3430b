"""The student's critics on held-out s04, one column per variant: the teacher at 7 steps and the plain student
(sampler-steps.jsonl, sampler-student.jsonl) beside each variant of sampler-student-critics-probe.jsonl (its `variant`).

    python docs/experiments/scripts/diffusion_fold.py --checkpoint runs/<variant>/fold-s04/final.safetensors --fold s04 \\
        --out docs/experiments/data/sampler-student-critics-probe.jsonl     # per variant (then its "variant" named)
    python docs/experiments/scripts/sampler_student_probe.py
"""

from __future__ import annotations

import json
from pathlib import Path

from sampler_steps import FIGURES

DATA = Path(__file__).resolve().parents[1] / "data"


def main(fold: str = "s04") -> None:
    columns = {"teacher, 7 steps": next(r for r in map(json.loads, open(DATA / "sampler-steps.jsonl"))
                                        if r["fold"] == fold and r["guidance"]["sample_steps"] == 7),
               "student": next(r for r in map(json.loads, open(DATA / "sampler-student.jsonl")) if r["fold"] == fold)}
    columns |= {r["variant"]: r for r in map(json.loads, open(DATA / "sampler-student-critics-probe.jsonl")) if r["fold"] == fold}
    print("| figure | " + " | ".join(columns) + " |")
    print("|---|" + "---:|" * len(columns))
    for key in FIGURES:
        print(f"| {key} | " + " | ".join(f"{r.get(key, float('nan')):.3f}" for r in columns.values()) + " |")


if __name__ == "__main__":
    main()
