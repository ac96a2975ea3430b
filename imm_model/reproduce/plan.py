"""Which training runs and evaluations each of the paper's tables needs (one list, shared runs reused)."""

from __future__ import annotations

from dataclasses import dataclass

from imm_model.evaluation.baselines import HEURISTIC_BASELINES
from imm_model.reproduce import k3hi_table
from imm_model.reproduce.jobs import HALF_SPLIT, TrainJob
from imm_model.reproduce.tasks import EvalJob

TABLES = ("afd", "fid", "ablation", "recognition", "models")
PAPER_TABLES = TABLES[:4]  # what `imm reproduce` writes unless --tables says otherwise
# the "models" table: the bundled GAN recipe beside the reaction diffusion model and the retrieval family (the 1-NN
# baseline as a model: its rows equal the 1-NN columns), each against the 1-NN retrieval
MODEL_RECIPES = ("imm-steer", "imm-diffusion", "retrieval")
ABLATION_RECIPES = ("imm-no-d", "imm-no-bone", "imm-no-continuity", "imm-no-fc", "imm-no-label")
SBU_SUBJECTS = ("s01", "s02", "s03", "s04", "s05", "s06", "s07")


@dataclass(frozen=True)
class ReproducePlan:
    seeds: tuple[int, ...] = (0,)
    tables: tuple[str, ...] = PAPER_TABLES
    folds: tuple[str, ...] = SBU_SUBJECTS
    epochs: int | None = None  # override every recipe's epochs (a diffusion recipe's optimizer steps; tiny runs in tests)
    classifier_epochs: int | None = None
    k3hi: bool = True  # the MoCap FID table on K3HI (with "fid"; needs ../shared/datasets/k3hi)

    def __post_init__(self) -> None:
        unknown = [t for t in self.tables if t not in TABLES]
        if unknown or not self.tables:
            raise ValueError(f"--tables: unknown table {unknown[0]!r}" if unknown else "--tables: none given")
        bad = [f for f in self.folds if f not in SBU_SUBJECTS]
        if bad or not self.folds:
            raise ValueError(f"--folds: {bad[0]!r} is not an SBU subject {SBU_SUBJECTS}" if bad else "--folds: none given")
        if not self.seeds or any(s < 0 for s in self.seeds):
            raise ValueError(f"--seeds: expected non-negative integers, not {self.seeds}")

    def _run(self, recipe: str, split: str, seed: int) -> TrainJob:
        return TrainJob(recipe, split, seed, self.epochs)

    def training_jobs(self) -> list[TrainJob]:
        recipes = ["imm", "men"] if {"afd", "fid"} & set(self.tables) else []
        if "ablation" in self.tables:
            recipes += ["imm", *ABLATION_RECIPES]
        if "recognition" in self.tables:
            recipes += ["imm"]
        if "models" in self.tables:
            recipes += list(MODEL_RECIPES)
        jobs = [self._run(r, f, s) for s in self.seeds for r in dict.fromkeys(recipes) for f in self.folds]
        if "recognition" in self.tables:
            jobs += [self._run("imm", HALF_SPLIT, s) for s in self.seeds]
        if self.k3hi and "fid" in self.tables:
            jobs += [self._run(r, split, s) for s in self.seeds for r in ("imm", "men") for split in k3hi_table.SPLITS]
        return jobs

    def eval_jobs(self) -> list[EvalJob]:
        jobs: list[EvalJob] = []
        n = self.classifier_epochs
        for s in self.seeds:
            for f in self.folds:
                imm = self._run("imm", f, s)
                if {"afd", "fid"} & set(self.tables):
                    baselines = (*HEURISTIC_BASELINES, "men")
                    jobs.append(EvalJob(imm, "final", baselines=baselines, men_run=self._run("men", f, s), classifier_epochs=n))
                if "ablation" in self.tables:
                    jobs += [EvalJob(self._run(r, f, s), "best", classifier_epochs=n) for r in ("imm", *ABLATION_RECIPES)]
                if "recognition" in self.tables:
                    jobs.append(EvalJob(imm, "final", kind="recognition", classifier_epochs=n))
                if "models" in self.tables:
                    jobs += [EvalJob(self._run(r, f, s), "final", baselines=("nn1",), classifier_epochs=n) for r in MODEL_RECIPES]
            if "recognition" in self.tables:
                jobs.append(EvalJob(self._run("imm", HALF_SPLIT, s), "final", kind="recognition", classifier_epochs=n))
            if self.k3hi and "fid" in self.tables:
                runs = [self._run(r, split, s) for r in ("imm", "men") for split in k3hi_table.SPLITS]
                jobs.append(EvalJob(runs[0], "final", kind="k3hi", also=tuple(runs[1:]), classifier_epochs=n))
        return jobs
