"""The training runs and evaluations `imm reproduce` needs, each keyed so that finished work is reused.

A training run is (recipe, split, seed) on one dataset bundle. Its directory is
RUNS/<recipe>-seed<seed>/fold-<split> (RUNS: `--runs`, default OUT/runs), the layout `imm train` writes and
`imm evaluate --run` reads.
`job.json` there holds the run's key: a hash of the recipe's full config, the split, the seed, the data and
the package version. A directory whose key differs is stale: it is moved aside (never deleted) and the run
starts again; a directory with the same key and no `done.json` is resumed from its last checkpoint.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import imm_model
from imm_model.outputs import write_atomic

HALF_SPLIT = "half"  # the recognition study's class-stratified half/half split of SBU (data/splits.py)


@dataclass(frozen=True)
class TrainJob:
    recipe: str  # a named recipe of any family (families/__init__.py)
    split: str  # a LOSO subject "sXX", HALF_SPLIT, or a K3HI split (reproduce/k3hi_table.py)
    seed: int
    epochs: int | None = None  # override of the recipe's length: the GAN's epochs, the diffusion model's steps (tiny runs in tests)

    @property
    def name(self) -> str:
        return f"{self.recipe} seed {self.seed} fold {self.split}"

    @property
    def dataset(self) -> str:
        return "k3hi" if self.split.startswith("k3hi") else "sbu"

    def run_dir(self, runs: Path) -> Path:
        return runs / f"{self.recipe}-seed{self.seed}" / f"fold-{self.split}"

    @property
    def family(self):
        """The registry's entry for the recipe's family."""
        from imm_model.families import load_recipe

        return load_recipe(self.recipe)[0]

    @property
    def cost(self) -> float:
        """Expected seconds on one lane of this 2-core machine (seed 0's records; a diffusion fold's 6000 steps about
        20 minutes), to run the longest first."""
        length = self.family.length_option
        if length == "steps":
            return 1200.0
        if length is None:
            return 1.0
        return 300.0 if self.dataset == "k3hi" else 220.0 if self.config().refit else 80.0

    def config(self):
        """The recipe's config, with this job's seed and length."""
        from imm_model.families import load_recipe

        family = load_recipe(self.recipe)[0]
        given = {"seed": self.seed} if "seed" in family.recipes()[family.default_recipe].to_dict() else {}
        if family.length_option:
            given[family.length_option] = self.epochs
        return load_recipe(self.recipe, **given)[1]

    def key(self, data_hash: str) -> str:
        """Only the fields that differ from TrainConfig's defaults count, so adding an option (with a default that
        keeps today's behaviour) does not invalidate finished runs."""
        config = self.config()
        cfg, default = config.to_dict(), type(config)().to_dict()
        changed = {k: v for k, v in cfg.items() if v != default.get(k, object())}
        text = json.dumps({"config": changed, "split": self.split, "seed": self.seed,
                           "data": data_hash, "code": imm_model.__version__}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_status(job: TrainJob, runs: Path, key: str) -> str:
    """'done', 'partial' (same key, resumable) or 'new' (nothing there, or a stale run that is moved aside)."""
    d = job.run_dir(runs)
    stamp = d / "job.json"
    if not d.exists() or not any(d.iterdir()):
        return "new"
    try:
        saved = json.loads(stamp.read_text())["key"]
    except (OSError, ValueError, KeyError, TypeError):
        saved = None
    if saved != key:
        aside = d.with_name(f"{d.name}.stale-{time.strftime('%Y%m%d-%H%M%S')}")
        d.rename(aside)  # never lose work: a run from another config or data stays readable
        return "new"
    return "done" if (d / "done.json").exists() else "partial"


def stamp_job(job: TrainJob, runs: Path, key: str) -> None:
    d = job.run_dir(runs)
    d.mkdir(parents=True, exist_ok=True)
    write_atomic(d / "job.json", json.dumps({"key": key, "job": asdict(job)}, indent=1) + "\n")


def mark_done(job: TrainJob, runs: Path, info: dict) -> None:
    write_atomic(job.run_dir(runs) / "done.json", json.dumps(info, indent=1) + "\n")


def copy_records(jobs: list[TrainJob], runs: Path, dest: Path) -> int:
    """Copy each finished run's small records (job.json, done.json and its cached evaluations: every *.json but the
    checkpoints' sidecars) to the same layout under `dest` -> how many runs. `--runs dest` then rebuilds the report
    without a checkpoint: the runs count as finished and their evaluations as cached. Kept beside the report because
    checkpoints are too large for a repository (60 runs per seed), while the records are what the tables are
    computed from."""
    import shutil

    copied = 0
    for job in jobs:
        src, dst = job.run_dir(runs), job.run_dir(dest)
        if not (src / "done.json").exists() or src.resolve() == dst.resolve():
            continue
        dst.mkdir(parents=True, exist_ok=True)
        for f in src.glob("*.json"):
            if not f.with_suffix(".safetensors").exists():  # best/last/final.json describe checkpoints left behind
                shutil.copy2(f, dst / f.name)
        copied += 1
    return copied
