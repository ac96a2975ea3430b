"""`imm reproduce` end to end on a tiny scale (2 epochs, 1 fold, local Ray), including a kill and a resume;
and the pieces it is built from: job keys, stale runs moved aside, the half split, the ablation recipes."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from imm_model.reproduce.jobs import TrainJob, run_status, stamp_job

TINY = ["--folds", "s04", "--epochs", "2", "--classifier-epochs", "2"]


def _reproduce(out: Path, env: dict, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "imm_model.cli", "reproduce", "--out", str(out), *TINY, *extra],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


@pytest.mark.slow
def test_tiny_reproduce_killed_then_resumed_writes_all_four_tables(tmp_path):
    pytest.importorskip("ray")
    env = os.environ | {"IMM_CACHE_DIR": str(tmp_path / "cache"), "RAY_USAGE_STATS_ENABLED": "0"}
    out = tmp_path / "rep"
    first = _reproduce(out, env)
    deadline = time.monotonic() + 240
    while not list(out.glob("runs/*/fold-*/done.json")) and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(first.pid, signal.SIGTERM)  # mid-way: at least one run finished, the others not
    first.wait(60)
    finished = {p: p.stat().st_mtime_ns for p in out.glob("runs/*/fold-*/done.json")}
    assert finished, first.stdout.read()
    assert not (out / "report.md").exists()

    second = _reproduce(out, env)
    log = second.communicate(timeout=600)[0]
    assert second.returncode == 0, log
    counts = re.search(r"(\d+) training runs: (\d+) finished already \(reused\)", log)
    assert counts and len(finished) <= int(counts.group(2)) < int(counts.group(1)), log
    assert all(p.stat().st_mtime_ns == t for p, t in finished.items())  # reused, not retrained
    report = (out / "report.md").read_text()
    for title in ("AFD on SBU (paper Table 1)", "FID on SBU (paper Table 2)", "K3HI in place of 2C", "Ablation on SBU (paper Table 4)",
                  "Recognition with synthesized data (paper Table 5)", "Where the paper's text and its code disagree"):
        assert title in report
    assert "imm-no-label" in report and "Missing" not in report
    assert (out / "afd.png").stat().st_size > 1000
    records = out / "records"  # the runs' small records, no checkpoint: enough to write the report again
    assert list(records.glob("*/fold-*/done.json")) and not list(records.rglob("*.safetensors"))
    again = tmp_path / "again"
    third = _reproduce(again, env, "--runs", str(records))  # everything is reused: no training, no evaluation
    log = third.communicate(timeout=300)[0]
    assert "0 to resume, 0 to train" in log and "0 to run" in log, log
    summary = lambda d: json.loads((d / "summary.json").read_text())["imm"]  # noqa: E731
    assert summary(again) == summary(out)
    interim = tmp_path / "interim"  # a seed not trained yet: listed as missing, nothing started
    fourth = _reproduce(interim, env, "--runs", str(records), "--seeds", "0,7", "--report-only")
    log = fourth.communicate(timeout=300)[0]
    assert fourth.returncode != 0 and "not done are left out" in log, log
    assert "evaluate imm seed 7 fold s04 (final)" in (interim / "report.md").read_text().split("## Missing")[1]
    assert summary(interim) == summary(out) and not list(records.glob("*-seed7"))


def test_a_run_with_another_key_is_moved_aside_not_deleted(tmp_path):
    job = TrainJob("imm", "s04", 0, epochs=2)
    assert run_status(job, tmp_path, "k1") == "new"
    stamp_job(job, tmp_path, "k1")
    (job.run_dir(tmp_path) / "last.safetensors").write_bytes(b"x")
    assert run_status(job, tmp_path, "k1") == "partial"
    assert run_status(job, tmp_path, "k2") == "new"
    aside = list(job.run_dir(tmp_path).parent.glob("fold-s04.stale-*"))
    assert len(aside) == 1 and json.loads((aside[0] / "job.json").read_text())["key"] == "k1"


def test_job_key_changes_with_recipe_seed_split_and_data():
    base = TrainJob("imm", "s04", 0)
    keys = {base.key("d1"), TrainJob("imm-no-d", "s04", 0).key("d1"), TrainJob("imm", "s04", 1).key("d1"),
            TrainJob("imm", "s03", 0).key("d1"), base.key("d2")}
    assert len(keys) == 5 and base.key("d1") == TrainJob("imm", "s04", 0).key("d1")


def test_the_models_table_trains_the_gan_and_the_diffusion_recipe_and_scores_each_against_the_1nn(tmp_path):
    from imm_model.checkpoint import final_checkpoint
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_DATA
    from imm_model.reproduce.plan import MODEL_RECIPES, PAPER_TABLES, ReproducePlan
    from imm_model.reproduce.tasks import train_run

    assert ReproducePlan().tables == PAPER_TABLES  # the paper's four unless asked
    plan = ReproducePlan(tables=("models",), folds=("s04",), seeds=(0, 1), epochs=2)
    assert {(j.recipe, j.seed) for j in plan.training_jobs()} == {(r, s) for r in MODEL_RECIPES for s in (0, 1)}
    assert len(plan.eval_jobs()) == 2 * len(MODEL_RECIPES)
    assert all(j.baselines == ("nn1",) and j.checkpoint == "final" for j in plan.eval_jobs())
    job = TrainJob("imm-diffusion", "s04", 0, epochs=2)  # a diffusion recipe's "epochs" are its optimizer steps
    assert job.config().steps == 2 and job.cost > TrainJob("imm-steer", "s04", 0).cost  # the longest first
    assert len({job.key("d"), TrainJob("imm-diffusion", "s04", 1, epochs=2).key("d"), TrainJob("imm-diffusion", "s04", 0).key("d")}) == 3
    info = train_run(job, tmp_path, SAMPLE_DATA, job.key("d"), threads=1)
    assert info["steps"] == 2 and json.loads((job.run_dir(tmp_path) / "done.json").read_text())["key"] == job.key("d")
    assert ReactionModel.load(final_checkpoint(job.run_dir(tmp_path))).settings.seed


def test_half_split_is_stratified_and_disjoint(sample_data):
    from imm_model.data.splits import half_split

    fold = half_split(sample_data.actions)
    assert len(np.intersect1d(fold.train, fold.test)) == 0 and len(fold.train) + len(fold.test) == len(sample_data)
    for c in range(len(sample_data.class_names)):
        n = (sample_data.actions == c).sum()
        assert (sample_data.actions[fold.train] == c).sum() == (n + 1) // 2


def test_ablation_recipes_remove_one_component_each():
    from imm_model.families.gan.config import ModelConfig
    from imm_model.families.gan.recipes import ABLATIONS, IMM

    assert ABLATIONS["imm-no-d"].lambda_adv == 0 and ABLATIONS["imm-no-bone"].lambda_bone == 0
    assert ABLATIONS["imm-no-continuity"].lambda_cont == 0
    assert ModelConfig.from_dict(ABLATIONS["imm-no-fc"].model).stream_fc is False
    assert ModelConfig.from_dict(ABLATIONS["imm-no-label"].model).label_input is False
    for cfg in ABLATIONS.values():
        assert cfg.lr_g == IMM.lr_g and cfg.epochs == IMM.epochs and not cfg.refit


def test_generator_without_stream_fc_reads_coordinates_directly():
    import torch

    from imm_model.families.gan.config import ModelConfig
    from imm_model.families.gan.generator import Generator

    cfg = ModelConfig(body_parts=((0, 1), (2, 3, 4), (5, 6), (7, 8), (9, 10, 11, 12, 13, 14)), stream_fc=False,
                      encoder_hidden=8, decoder_hidden=8, attention_dim=8)
    g = Generator(cfg)
    assert all(isinstance(e, torch.nn.Identity) for e in g.embed)
    out = g(torch.randn(2, 5, 45), torch.eye(6)[:2], torch.tensor([5, 3]))
    assert out.shape == (2, 5, 45) and torch.isfinite(out).all()


def test_runner_reports_a_failed_job_and_finishes_the_others():
    """A failed job is reported and the others finish; a job that needs a failed one is skipped, one that needs a
    finished one runs (evaluations wait for their training runs)."""
    from imm_model.reproduce.runner import Runner, Task

    tasks = [Task("ok", int, ("3",)), Task("bad", int, ("x",)), Task("after ok", abs, (-2,), needs=(0,)),
             Task("after bad", abs, (-5,), needs=(1, 0))]
    with Runner(backend="local") as r:
        results = r.run(tasks, "test")
    assert results[0] == (True, 3) and results[2] == (True, 2)
    assert results[1][0] is False and "invalid literal" in results[1][1]
    assert results[3] == (False, "skipped: it needs bad, which failed")


def test_runner_starts_the_longest_ready_job_first():
    """With one lane, jobs run by expected cost; a long job that becomes ready (its needs finished) goes before the
    shorter ones that were ready from the start, so it cannot end up alone at the end."""
    from imm_model.reproduce.runner import Runner, Task

    tasks = [Task("short", time.time_ns, (), cost=1), Task("long", time.time_ns, (), cost=9),
             Task("medium", time.time_ns, (), cost=5), Task("longest, after long", time.time_ns, (), needs=(1,), cost=100)]
    with Runner(cpus_per_task=os.cpu_count() or 1, backend="local") as r:
        assert r.width == 1
        results = r.run(tasks, "test")
    started = sorted(range(len(tasks)), key=lambda i: results[i][1])
    assert [tasks[i].name for i in started] == ["long", "longest, after long", "medium", "short"]


@pytest.mark.parametrize("args, message", [
    (["--tables", "bogus"], "--tables: unknown table 'bogus'"),
    (["--folds", "s09"], "--folds: 's09' is not an SBU subject"),
    (["--seeds", "x"], "expected comma-separated integers"),
    (["--cpus-per-task", "0"], "cpus per task must be >= 1"),
    (["--data", "/nonexistent/bundle.npz"], "/nonexistent/bundle.npz"),
])
def test_bad_arguments_get_one_line(tmp_path, args, message):
    proc = subprocess.run([sys.executable, "-m", "imm_model.cli", "reproduce", "--out", str(tmp_path / "r"), *args],
                          capture_output=True, text=True, timeout=120)
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 2 and last.startswith("imm reproduce: error:") and message in last, proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "r" / "runs").exists()
