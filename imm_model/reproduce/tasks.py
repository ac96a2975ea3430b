"""What one worker does for `imm reproduce`: train one run, or evaluate one checkpoint on its fold.

These run in Ray workers or local processes (reproduce/runner.py), so they take plain arguments, load what
they need themselves and write their results next to the run (resumable: a finished result is read back).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, replace
from pathlib import Path

from imm_model.outputs import FolderLock, write_atomic
from imm_model.reproduce.jobs import HALF_SPLIT, TrainJob, mark_done, stamp_job


def training_data(data_path: Path, split: str):
    """The training data, and the held-out subject Trainer takes (None for the half and K3HI splits: their training
    part only)."""
    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import half_split

    if split.startswith("k3hi"):
        from imm_model.reproduce.k3hi_table import shared_data

        data, splits = shared_data()
        return data.subset(splits[split][0]), None
    data = InteractionDataset.load(data_path)
    if split == HALF_SPLIT:
        return data.subset(half_split(data.actions).train), None
    return data, split


def train_run(job: TrainJob, runs: Path, data_path: Path, key: str, threads: int) -> dict:
    """Train (or resume) one run to the end, refit included -> what done.json records."""
    import torch

    torch.set_num_threads(threads)
    t0 = time.perf_counter()
    data, subject = training_data(data_path, job.split)
    stamp_job(job, runs, key)
    with FolderLock(job.run_dir(runs), "run"):  # e.g. a trainer of a killed reproduce that is still running
        done = job.family.train(job.config(), data, subject, job.run_dir(runs), resume=True, progress=False)
        info = {"key": key} | done.counts
        info["seconds"] = round(time.perf_counter() - t0, 1)
        mark_done(job, runs, info)
    return info


@dataclass(frozen=True)
class EvalJob:
    run: TrainJob
    checkpoint: str  # "final" (what the run ships) or "best" (the selection model, for the ablation table)
    # "metrics" (evaluation/loso.py), "recognition" (reproduce/recognition.py) or "k3hi" (reproduce/k3hi_table.py)
    kind: str = "metrics"
    baselines: tuple[str, ...] = ()
    men_run: TrainJob | None = None  # the label-free run whose checkpoint is the "men" baseline
    also: tuple[TrainJob, ...] = ()  # further runs it reads (the K3HI table: every recipe and split)
    classifier_epochs: int | None = None  # override (tiny runs in tests)

    @property
    def name(self) -> str:
        what = {"metrics": "evaluate", "recognition": "recognition study on", "k3hi": "K3HI table from"}[self.kind]
        return f"{what} {self.run.name} ({self.checkpoint})"

    @property
    def needs(self) -> tuple[TrainJob, ...]:
        return (self.run, *((self.men_run,) if self.men_run else ()), *self.also)

    @property
    def cost(self) -> float:
        """Expected seconds on one lane (seed 0's log), to run the longest first: the half split's study trains three
        classifiers; a fold's first evaluation may train its three judges."""
        if self.kind == "recognition":
            return 200.0 if self.run.split == HALF_SPLIT else 80.0
        return 80.0 if self.kind == "k3hi" else 60.0 if self.checkpoint == "final" else 10.0

    def result_path(self, runs: Path) -> Path:
        return self.run.run_dir(runs) / f"{'eval' if self.kind == 'metrics' else self.kind}-{self.checkpoint}.json"

    def checkpoint_path(self, runs: Path) -> Path:
        from imm_model.checkpoint import final_checkpoint

        run_dir = self.run.run_dir(runs)
        return final_checkpoint(run_dir) if self.checkpoint == "final" else run_dir / "best.safetensors"

    def key(self, runs: Path) -> str:
        """Changes when the run, the men run, the baselines or the classifiers change."""
        from imm_model.model.classifier_config import INTERACTION

        stamp = lambda job: json.loads((job.run_dir(runs) / "done.json").read_text())["key"]  # noqa: E731
        # the recognition study's classifier seed; a key without one is a half-split study over three seeds (older)
        seeds = [[INTERACTION.seed]] if self.kind == "recognition" else []
        text = json.dumps([[stamp(job) for job in self.needs], self.checkpoint, self.kind, self.baselines,
                           self.classifier_epochs, *seeds])
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def options(self, runs: Path):
        from imm_model.checkpoint import final_checkpoint
        from imm_model.evaluation.loso import EvalOptions
        from imm_model.model.classifier_config import FOLLOWER, FOLLOWER_JUDGE, INTERACTION

        defaults = {"interaction": INTERACTION, "follower": FOLLOWER, "judge": FOLLOWER_JUDGE}
        n = self.classifier_epochs
        judges = {k: replace(cfg, epochs=n) for k, cfg in defaults.items()} if n else {}
        men = self.men_run
        return EvalOptions(baselines=self.baselines, progress=False, **judges,
                           men_checkpoint=(lambda s: final_checkpoint(men.run_dir(runs))) if men else None)


def cached_result(job: EvalJob, runs: Path) -> dict | None:
    path = job.result_path(runs)
    try:
        saved = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return saved["result"] if saved.get("key") == job.key(runs) else None


def evaluate_run(job: EvalJob, runs: Path, data_path: Path, threads: int) -> dict:
    """One checkpoint on its split: every metric of docs/evaluation-protocol.md (LOSO fold), the recognition study, or the
    K3HI table (every recipe and split of the seed)."""
    import torch

    from imm_model.checkpoint import final_checkpoint
    from imm_model.data.dataset import InteractionDataset
    from imm_model.inference import ReactionModel

    torch.set_num_threads(threads)
    if (result := cached_result(job, runs)) is not None:
        return result
    if job.kind == "k3hi":
        from imm_model.reproduce.k3hi_table import scores

        checkpoints: dict[str, dict] = {}
        for run in (job.run, *job.also):
            checkpoints.setdefault(run.recipe, {})[run.split] = final_checkpoint(run.run_dir(runs))
        result = scores(checkpoints, job.classifier_epochs)
    elif job.kind == "recognition":
        result = _recognition(job, ReactionModel.load(job.checkpoint_path(runs)), InteractionDataset.load(data_path))
    else:
        from imm_model.evaluation.loso import evaluate_fold

        model, data = ReactionModel.load(job.checkpoint_path(runs)), InteractionDataset.load(data_path)
        result = evaluate_fold(model, data, job.run.split, job.options(runs))
    result |= {"seed": job.run.seed}
    write_atomic(job.result_path(runs), json.dumps({"key": job.key(runs), "result": result}) + "\n")
    return result


def _recognition(job: EvalJob, model, data) -> dict:
    from imm_model import cache
    from imm_model.data.splits import half_split, loso_fold
    from imm_model.reproduce.recognition import study

    if job.run.split == HALF_SPLIT:  # the paper's protocol, and the clean one
        split, protocols, real_only = half_split(data.actions), ("clean", "paper"), None
    else:  # the real-only classifier is the fold's evaluation classifier, trained once (cached)
        split, protocols = loso_fold(data.subject_pairs, job.run.split), ("clean",)
        real_only = lambda cfg: cache.fold_classifier(cfg, data, job.run.split, progress=False)  # noqa: E731
    return study(model, data, split.train, split.test, protocols, job.classifier_epochs, seed=job.run.seed,
                 real_only=real_only)
