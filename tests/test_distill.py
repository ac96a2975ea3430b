"""The few-step student distilled from the diffusion sampler (families/diffusion/distill.py): its label pool, one
network call per step whatever the label, training that reproduces the sampler it ships with, and the checks on its
teacher. Tiny networks trained for a few steps on the bundled SBU data (real data; the numbers are behaviour, not
results)."""

from __future__ import annotations

import csv
from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.errors import CheckpointError
from imm_model.families import load_model
from imm_model.families.diffusion.distill import LABEL_KINDS, ReactionCritic, StudentTrainer, pool_labels
from imm_model.families.diffusion.recipes import IMM_DIFFUSION, IMM_DIFFUSION_STUDENT
from imm_model.families.diffusion.sampler import Guidance, sample, schedule_step
from imm_model.families.diffusion.trainer import DiffusionTrainer

TEACHER = replace(IMM_DIFFUSION, name="tiny-teacher",
                  model=dict(width=16, layers=1, heads=2, ff_mult=1, dropout=0.0, leader_noise=True),
                  guidance=dict(label_scale=2.5, sample_steps=3, guided_below=0.3, leader_noise=0.3, part_join=True,
                                join_outputs=True),
                  steps=6, batch_size=8, warmup_steps=2, checkpoint_every=6)


@pytest.fixture(scope="module")
def teacher_runs(tmp_path_factory, sample_data):
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("teacher")
    DiffusionTrainer(TEACHER, sample_data, "s04", out / "fold-s04").fit(progress=False)
    return str(out / "fold-{fold}" / "final.safetensors")


def student_config(teacher: str, **changes):
    """The student recipe, small; without its label critic unless asked (the fold's classifier takes minutes to train)."""
    return replace(IMM_DIFFUSION_STUDENT, teacher=teacher, pool_rows=48, steps=30, batch_size=16, lr=3e-3, warmup_steps=0,
                   **({"lambda_label": 0.0} | changes))


@pytest.fixture(scope="module")
def student(teacher_runs, sample_data, tmp_path_factory):
    trainer = StudentTrainer(student_config(teacher_runs, window_share=0.5), sample_data, "s04",
                             tmp_path_factory.mktemp("student"))
    trainer.draw_pool(progress=False)
    rows = torch.arange(len(trainer.pool["length"]))

    def pool_error() -> float:
        with torch.no_grad():
            x0, mask = trainer.student_sample(trainer.net.eval(), rows)
        m = mask[..., None].float()
        return float((((x0 - trainer.pool["target"][:, : x0.shape[1]]) ** 2) * m).sum() / (m.sum() * x0.shape[-1]))

    before = pool_error()
    path = trainer.fit(progress=False)  # draws the same pool again (its seed) and trains on it
    return trainer, path, before, pool_error()


def test_the_pool_asks_for_labels_as_the_front_ends_do():
    labels = pool_labels(np.random.default_rng(0), 6000, 6)
    assert labels.shape == (6000, 6) and labels.dtype == np.float32
    counts = (labels != 0).sum(1)
    shares = {k: float(np.mean(counts == k)) for k in range(4)}
    kinds = dict(LABEL_KINDS)
    assert abs(shares[0] - kinds["no label"]) < 0.02
    assert abs(shares[1] - kinds["one class at +1"] - kinds["one class at a value in -1..2"]) < 0.03
    assert abs(shares[3] - kinds["three classes at values in -1..1.5"]) < 0.03
    assert ((labels == -1).sum(1) == 1).mean() > 0.05  # one performed, another avoided
    assert labels.min() >= -1 and labels.max() <= 2


def test_a_student_is_asked_once_per_step_whatever_the_label():
    b, t, d = 3, 5, 6
    calls = []

    def denoise(x_t, step, leader_on, label, label_on):
        calls.append((len(x_t), label.copy(), label_on.copy()))
        return np.zeros_like(x_t)

    labels = np.array([[1, 0, 0], [0.5, -1, 0], [1, 1, 1.5]], np.float32)
    noise = np.random.default_rng(0).standard_normal((b, t, d)).astype(np.float32)
    mask = np.ones((b, t), bool)
    guidance = Guidance(sample_steps=2)
    sample(denoise, np.zeros((b, t, d), np.float32), mask, labels, noise, guidance, 100, composed_label=True)
    assert len(calls) == 2 and all(n == b for n, _, _ in calls)
    assert all(np.array_equal(label, labels) and on.all() for _, label, on in calls)
    calls.clear()
    sample(denoise, np.zeros((b, t, d), np.float32), mask, labels, noise, guidance, 100)
    assert len(calls) == 2 and all(n == 4 * b for n, _, _ in calls)  # the teacher: the leader term and three classes


def test_training_brings_the_student_to_its_teacher(student):
    _, _, before, after = student
    assert after < 0.8 * before


def test_the_student_ships_the_sampler_it_was_trained_through(student, sample_data):
    trainer, path, _, _ = student
    model = load_model(path)
    assert model.config.composed_label and model.guidance.sample_steps == 2
    assert (path.parent / model.info["teacher"]["path"]).samefile(trainer.cfg.teacher.format(fold="s04"))
    pool = trainer.pool
    level = schedule_step(model.guidance.leader_noise, model.config.diffusion_steps)
    rows = np.flatnonzero(pool["level"].numpy() == level)[:4]
    assert len(rows)
    w = model.weights
    leaders = [(pool["leader"][r, : pool["length"][r]].numpy() * w["leader_std"] + w["leader_mean"]).reshape(-1, 15, 3)
               for r in rows]
    seeds = trainer.seeds[rows].tolist()
    made = model._sample(leaders, pool["label"][rows].numpy(), seeds)
    with torch.no_grad():
        x0, _ = trainer.student_sample(trainer.ema, torch.as_tensor(rows))
    for k, follower in enumerate(made):
        t = len(follower)
        trained = (x0[k, :t].numpy() * w["follower_std"] + w["follower_mean"]).reshape(t, -1, 3)
        assert np.abs(trained - follower).max() < 1e-3
    # a clip is then smoothed in time as the recipe asks (the model's `_network`; a window keeps its given frames)
    assert model.guidance.smoothing == IMM_DIFFUSION_STUDENT.guidance["smoothing"] > 0
    clip = model.synthesize(leaders[0], {"kicking": 1.0}, seed=seeds[0])
    model.guidance = replace(model.guidance, smoothing=0.0)
    assert not np.allclose(clip, model.synthesize(leaders[0], {"kicking": 1.0}, seed=seeds[0]), atol=1e-4)


def test_a_window_row_is_a_long_takes_window_and_the_student_samples_it_as_the_windows_do(student):
    """A window row: a slice of a clip row's leader and noise, given the teacher's reaction to its first frames, its
    target the teacher's continuation of them; the student's pool sampler makes of it what the model's sampler makes
    of a window of a long take (windows.py: the given frames held, the start noised from them at CONTINUE_LEVEL)."""
    from imm_model.families.diffusion.windows import CONTINUE_LEVEL

    trainer, path, _, _ = student
    pool, model = trainer.pool, load_model(path)
    windows = np.flatnonzero(pool["known"].numpy() > 0)
    clips = np.flatnonzero(pool["known"].numpy() == 0)
    assert 0.25 < len(windows) / len(clips) < 0.75  # window_share 0.5
    assert (pool["start"][windows] == schedule_step(CONTINUE_LEVEL, 100)).all()
    assert (pool["known"][windows] < pool["length"][windows]).all()
    # each window's leader and given frames are a stretch of its clip row's leader and teacher reaction
    w = int(windows[0])
    t, k, r, a = (int(pool[key][w]) for key in ("length", "known", "source", "offset"))
    assert r in clips and trainer.seeds[r] == trainer.seeds[w]
    assert torch.equal(pool["leader"][r, a:a + t], pool["leader"][w, :t])
    assert torch.allclose(pool["given"][w, :k], pool["target"][r, a:a + k])
    rows = windows[:4]
    wts = model.weights
    with torch.no_grad():
        x0, _ = trainer.student_sample(trainer.ema, torch.as_tensor(rows))
    for i, row in enumerate(rows):
        t, k = int(pool["length"][row]), int(pool["known"][row])
        leader = (pool["leader"][row, :t].numpy() * wts["leader_std"] + wts["leader_mean"]).reshape(t, -1, 3)
        given = (pool["given"][row, :t].numpy() * wts["follower_std"] + wts["follower_mean"]).reshape(t, -1, 3)
        made = model._sample([leader], pool["label"][row][None].numpy(), [int(trainer.seeds[row])],
                             [pool["noise"][row, :t].numpy()], [pool["leader_noise"][row, :t].numpy().astype(np.float64)],
                             [(given, k)], CONTINUE_LEVEL)[0]
        trained = (x0[i, :t].numpy() * wts["follower_std"] + wts["follower_mean"]).reshape(t, -1, 3)
        assert np.abs(trained - made).max() < 1e-3
        assert np.abs(made[:k] - given[:k]).max() < 1e-4  # the given frames stay as given


def test_refreshed_windows_continue_the_students_own_reaction(teacher_runs, sample_data, tmp_path):
    """window_refresh: a window row is given the student's own reaction to its clip, and its target becomes the
    teacher's continuation of those frames (the teacher's sampler on the window, given them)."""
    from imm_model.families.diffusion.windows import CONTINUE_LEVEL

    trainer = StudentTrainer(student_config(teacher_runs, window_share=0.5, window_refresh=10), sample_data, "s04", tmp_path)
    trainer.draw_pool(progress=False)
    pool = trainer.pool
    before = pool["target"].clone()
    for _ in range(5):
        trainer.train_step()
    trainer.refresh_windows()
    windows = torch.nonzero(pool["known"] > 0)[:, 0]
    w = int(windows[0])
    t, k, r, a = (int(pool[key][w]) for key in ("length", "known", "source", "offset"))
    with torch.no_grad():
        own, _ = trainer.student_sample(trainer.ema, torch.tensor([r]))
    assert torch.allclose(pool["given"][w, :k], own[0, a:a + k], atol=1e-5)
    assert not torch.allclose(pool["target"][w, :t], before[w, :t])
    clips = torch.nonzero(pool["known"] == 0)[:, 0]
    assert torch.equal(pool["target"][clips], before[clips])  # the clips keep the teacher's reaction
    model, wts = trainer.teacher, trainer.teacher.weights
    leader = (pool["leader"][w, :t].numpy() * wts["leader_std"] + wts["leader_mean"]).reshape(t, -1, 3)
    given = (pool["given"][w, :t].numpy() * wts["follower_std"] + wts["follower_mean"]).reshape(t, -1, 3)
    spread = int(pool["level"][w]) / (trainer.model_cfg.diffusion_steps - 1)
    guidance = model.guidance
    model.guidance = replace(guidance, leader_noise=spread)
    made = model._sample([leader], pool["label"][w][None].numpy(), [int(trainer.seeds[w])], [pool["noise"][w, :t].numpy()],
                         [pool["leader_noise"][w, :t].numpy()], [(given, k)], CONTINUE_LEVEL)[0]
    model.guidance = guidance
    target = (pool["target"][w, :t].numpy() * wts["follower_std"] + wts["follower_mean"]).reshape(t, -1, 3)
    assert np.abs(target - made).max() < 1e-4


def test_the_student_answers_the_api_with_seeds_mixes_and_parts(student, sample_data):
    model = load_model(student[1])
    leader = sample_data.world(0)[0]
    one = model.synthesize(leader, {"kicking": 1}, seed=0)
    assert np.array_equal(one, model.synthesize(leader, {"kicking": 1}, seed=0))
    assert not np.allclose(one, model.synthesize(leader, {"kicking": 1}, seed=1))
    assert not np.allclose(one, model.synthesize(leader, {"kicking": 1, "punching": -1}, seed=0))
    parts = model.synthesize(leader, {"upper:kicking": 1, "lower:punching": 1}, seed=0)
    assert parts.shape == one.shape and np.isfinite(parts).all()


def test_a_student_s_teacher_makes_its_long_takes_and_live_reactions_when_it_is_there_as_it_was(student, sample_data,
                                                                                               teacher_runs, tmp_path):
    """The student's sidecar names its teacher's file from its own folder: loaded, the student samples a clip itself
    and a long take and a live reaction through the teacher (exactly the teacher's), its spread followed there; a
    moving slider drafts a long take with the student's own windows, and a clip with nothing (the student draws it).
    Without that teacher file, or with other weights in it, the student makes them itself."""
    import json
    import os
    import shutil

    from imm_model.checkpoint import sidecar_path

    path = student[1]
    named = json.loads(sidecar_path(path).read_text())["teacher"]["path"]
    teacher_file = teacher_runs.format(fold="s04")
    assert not os.path.isabs(named) and os.path.samefile(path.parent / named, teacher_file)
    model, teacher = load_model(path), load_model(teacher_file)
    assert model.takes is not None and model.takes.path.samefile(teacher_file)
    leader = sample_data.world(0)[0]
    take = np.concatenate([leader, leader[::-1], leader, leader[::-1]])
    assert len(take) > model.window >= len(leader)
    label = {"kicking": 1, "punching": -0.5}
    assert np.array_equal(model.synthesize(take, label, seed=3), teacher.synthesize(take, label, seed=3))
    assert not np.allclose(model.synthesize(leader, label, seed=3), teacher.synthesize(leader, label, seed=3))
    assert not np.allclose(model.draft.synthesize(take, label, seed=3), teacher.synthesize(take, label, seed=3))
    assert model.draft_for(len(take)) is model.draft and model.draft_for(len(leader)) is None  # a clip: itself, at once
    teacher.attach_draft(load_model(path))  # the teacher opened alone, the student its draft: drafting a take, fast
    assert teacher.draft_for(len(take)).takes is None
    model.spread = teacher.spread = 0.6
    assert model.takes.spread == model.draft.spread == 0.6
    assert np.array_equal(model.synthesize(take, label, seed=3), teacher.synthesize(take, label, seed=3))
    live, own = model.online(label, seed=2), teacher.online(label, seed=2)
    pushed = [(live.push(f), own.push(f)) for f in leader]
    assert all((a is None and b is None) or np.array_equal(a, b) for a, b in pushed)

    alone = tmp_path / "alone"  # the student copied without its teacher
    alone.mkdir()
    shutil.copy(path, alone / path.name)
    shutil.copy(sidecar_path(path), sidecar_path(alone / path.name))
    assert load_model(alone / path.name).takes is None
    other = tmp_path / "other"  # beside a teacher file with other weights
    (other / "student").mkdir(parents=True)
    (other / "student" / named).parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, other / "student" / path.name)
    shutil.copy(sidecar_path(path), sidecar_path(other / "student" / path.name))
    shutil.copy(student[1], other / "student" / named)  # a student's weights where the teacher should be
    shutil.copy(sidecar_path(student[1]), sidecar_path(other / "student" / named))
    special = tmp_path / "special"  # its sidecar naming a device where the teacher should be: not read
    special.mkdir()
    shutil.copy(path, special / path.name)
    meta = json.loads(sidecar_path(path).read_text())
    meta["teacher"]["path"] = "/dev/zero"
    sidecar_path(special / path.name).write_text(json.dumps(meta))
    assert load_model(special / path.name).takes is None
    lonely = load_model(other / "student" / path.name)
    assert lonely.takes is None and not np.array_equal(lonely.synthesize(take, label, seed=3), teacher.synthesize(take, label, seed=3))


def test_a_teacher_that_saw_the_fold_is_refused_in_one_line(teacher_runs, sample_data, tmp_path):
    with pytest.raises(CheckpointError, match="held out s04, the student s01") as err:
        StudentTrainer(student_config(teacher_runs.format(fold="s04")), sample_data, "s01", tmp_path)
    assert "\n" not in str(err.value)


def test_a_teacher_of_another_family_is_refused_in_one_line(sample_data, tmp_path):
    from imm_model.paths import SAMPLE_GAN

    with pytest.raises(CheckpointError, match="imm_sbu.safetensors: not a diffusion model"):
        StudentTrainer(student_config(str(SAMPLE_GAN)), sample_data, "s04", tmp_path)


def test_a_student_needs_a_teacher_and_a_teacher_a_student():
    with pytest.raises(ValueError, match="teacher"):
        replace(IMM_DIFFUSION_STUDENT, teacher="")
    with pytest.raises(ValueError, match="teacher"):
        replace(IMM_DIFFUSION, teacher="runs/x/fold-{fold}/final.safetensors")
    with pytest.raises(ValueError, match="lambda_adversarial"):
        replace(IMM_DIFFUSION, lambda_adversarial=0.1)
    with pytest.raises(ValueError, match="lambda_label"):
        replace(IMM_DIFFUSION, lambda_label=0.1)
    with pytest.raises(ValueError, match="window_share"):
        replace(IMM_DIFFUSION, window_share=0.5)
    with pytest.raises(ValueError, match="window_refresh"):
        replace(IMM_DIFFUSION_STUDENT, window_share=0.0, window_refresh=500)


def test_the_critic_learns_to_tell_a_reaction_from_one_held_still_and_reads_the_label(student):
    """Real: the teacher's reactions. Fake: the same reactions held at their mean pose (what an averaging student
    drifts towards). A few Adam steps of the hinge loss separate them; the label enters the score."""
    trainer = student[0]
    torch.manual_seed(0)
    pool = trainer.pool
    rows = torch.arange(32)
    t = int(pool["length"][rows].max())
    mask = torch.arange(t)[None] < pool["length"][rows][:, None]
    m = mask[..., None].float()
    leader, real, label = pool["leader"][rows, :t] * m, pool["target"][rows, :t] * m, pool["label"][rows]
    still = (real.sum(1, keepdim=True) / m.sum(1, keepdim=True)) * m
    critic = ReactionCritic(real.shape[-1], label.shape[-1])
    opt = torch.optim.Adam(critic.parameters(), lr=1e-3, betas=(0.5, 0.999))
    for _ in range(60):
        loss = (torch.relu(1 - critic(leader, real, label, mask)).mean()
                + torch.relu(1 + critic(leader, still, label, mask)).mean())
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        assert (critic(leader, real, label, mask) > critic(leader, still, label, mask)).float().mean() > 0.9
        assert not torch.allclose(critic(leader, real, label, mask), critic(leader, real, -label, mask))


def test_a_student_with_a_critic_trains_both_and_logs_their_terms(teacher_runs, sample_data, tmp_path):
    trainer = StudentTrainer(student_config(teacher_runs, lambda_adversarial=0.5), sample_data, "s04", tmp_path)
    before = [p.detach().clone() for p in trainer.critic.parameters()]
    trainer.fit(progress=False)
    assert any(not torch.equal(a, b) for a, b in zip(before, trainer.critic.parameters(), strict=True))
    rows = list(csv.DictReader(open(tmp_path / "log.csv")))
    assert rows and float(rows[-1]["critic"]) > 0 and float(rows[-1]["adversarial"]) != 0


@pytest.mark.parametrize("extra, message", [([], "the student's teacher not found (train it first: imm train --config "
                                                 "imm-diffusion --fold s04"),
                                            (["--resume"], "--resume: a student or a live reactor is trained in one go")])
def test_the_student_recipe_at_the_command_line_says_what_is_missing_in_one_line(tmp_path, monkeypatch, capsys, extra,
                                                                                 message):
    from imm_model.cli import main

    monkeypatch.chdir(tmp_path)  # no runs/imm-diffusion here: the recipe's teacher is missing
    assert main(["train", "--config", "imm-diffusion-student", "--fold", "s04", "--out", "runs/s", "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_the_label_critic_reads_what_each_row_performs_and_skips_rows_that_perform_nothing(teacher_runs, sample_data, tmp_path,
                                                                                           monkeypatch):
    """lambda_label: the fold's follower classifier (here a quick one) scores a student's reaction against the classes
    its row performs, as shares; a row that performs nothing (no label, or only avoided classes) adds nothing."""
    import torch.nn.functional as F

    from imm_model import cache
    from tests.test_training_terms import quick_follower_classifier

    quick = quick_follower_classifier(sample_data)
    asked = []
    monkeypatch.setattr(cache, "fold_classifier", lambda cfg, data, subject, **k: asked.append(subject) or quick)
    trainer = StudentTrainer(student_config(teacher_runs, lambda_label=0.5), sample_data, "s04", tmp_path)
    assert asked == ["s04"]
    trainer.draw_pool(progress=False)
    rows = torch.arange(24)
    with torch.no_grad():
        x0, mask = trainer.student_sample(trainer.net.eval(), rows)
        label = torch.zeros(24, 6)
        label[:8, 0] = 1.0  # performs kicking
        label[8:16, 1], label[8:16, 2] = 1.0, 1.0  # performs two classes: half each
        label[16:, 3] = -1.0  # avoids a class only: nothing performed
        loss = trainer.label_loss(x0, mask, label)
        follower = x0[:16] * trainer.follower_scale["follower_std"] + trainer.follower_scale["follower_mean"]
        logits = quick(follower, mask[:16].sum(-1))
        target = label[:16] / label[:16].sum(-1, keepdim=True)
        assert torch.allclose(loss, F.cross_entropy(logits, target))
        assert torch.equal(trainer.label_loss(x0[16:], mask[16:], label[16:]), torch.zeros(()))
    trainer.fit(progress=False)
    rows = list(csv.DictReader(open(tmp_path / "log.csv")))
    assert float(rows[-1]["label"]) > 0
