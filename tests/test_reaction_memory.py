"""The diffusion sampler's reaction memory: which real reactions it retrieves, how the signed label weighs them, and
the sampler started from them (on the bundled SBU data; the tiny model's outputs are behaviour, not results)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from imm_model.data.splits import loso_fold
from imm_model.errors import LabelError
from imm_model.families.diffusion.reaction_memory import NEIGHBOURS, RESAMPLED_FRAMES, ReactionMemory, resample
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_GAN
from tests.test_diffusion import leader, tiny_model  # noqa: F401 - fixtures


@pytest.fixture(scope="module")
def memory(sample_data):
    return ReactionMemory.from_dataset(sample_data, loso_fold(sample_data.subject_pairs, "s04").train)


def test_resample_keeps_the_ends_and_interpolates():
    motion = np.arange(5, dtype=np.float32)[:, None, None] * np.ones((1, 2, 3), np.float32)
    out = resample(motion, 9)
    assert out.shape == (9, 2, 3) and out[0, 0, 0] == 0 and out[-1, 0, 0] == 4 and np.isclose(out[1, 0, 0], 0.5)
    assert np.array_equal(resample(motion[:1], 4), np.repeat(motion[:1], 4, 0))


def test_a_seed_picks_one_of_each_classs_nearest_leaders(memory, sample_data):
    test = loso_fold(sample_data.subject_pairs, "s04").test
    query_leader = sample_data.canonical(int(test[0]))[0]
    picks = np.stack([memory.picks(query_leader, seed)[0] for seed in range(40)])  # (seeds, C)
    query = resample(query_leader, RESAMPLED_FRAMES).reshape(RESAMPLED_FRAMES, -1, 3)
    dist = np.linalg.norm(memory.leaders.reshape(len(memory.leaders), RESAMPLED_FRAMES, -1, 3) - query, axis=-1).mean((1, 2))
    for c in range(memory.num_classes):
        members = np.flatnonzero(memory.classes == c)
        nearest = set(members[np.argsort(dist[members])[:NEIGHBOURS]].tolist())
        assert set(picks[:, c].tolist()) == nearest  # every seed picks among them, and 40 seeds reach all of them
    assert np.array_equal(memory.picks(query_leader, 7)[0], memory.picks(query_leader, 7)[0])


def test_the_mixture_follows_the_signed_label_continuously(memory):
    distance = np.array([0.30, 0.20, 0.25, 0.50, 0.40, 0.22])
    one = memory.mixture_weights(np.array([0, 1.0, 0, 0, 0, 0]), distance)
    assert np.allclose(one, np.eye(6)[1])  # +1 on a class: that class's reaction alone
    mix = memory.mixture_weights(np.array([0, 1.0, 0, 1.0, 0, 0]), distance)
    assert np.allclose(mix, 0.5 * (np.eye(6)[1] + np.eye(6)[3]))  # two at +1 (or beyond): half each
    assert np.allclose(memory.mixture_weights(np.array([0, 2.0, 0, 2.0, 0, 0]), distance), mix)
    neutral = memory.mixture_weights(np.zeros(6), distance)
    assert neutral.argmax() == 1 and np.isclose(neutral.sum(), 1)  # label-free: the nearest class leads
    avoided = memory.mixture_weights(np.array([0, -1.0, 0, 0, 0, 0]), distance)
    assert avoided[1] == 0 and avoided.argmax() == 5 and np.isclose(avoided.sum(), 1)  # -1 never starts the reaction
    steps = [memory.mixture_weights(np.array([0, 0, v, 0, 0, 0]), distance) for v in np.linspace(0, 1, 21)]
    assert max(np.abs(b - a).max() for a, b in zip(steps, steps[1:], strict=False)) <= 0.05 + 1e-9  # no jump
    assert np.allclose(memory.mixture_weights(-np.ones(6), distance).sum(), 1)


def test_the_start_is_a_real_reaction_fitted_to_the_leaders_length(memory, sample_data):
    short_leader = resample(sample_data.canonical(0)[0], 30)  # another length than any follower it retrieves
    index, _ = memory.picks(short_leader, 0)
    start = memory.start(short_leader, np.eye(6)[2], 0)
    assert start.shape == short_leader.shape
    assert np.allclose(start, resample(memory.followers[index[2]], 30), atol=1e-6)


def test_a_memory_needs_every_class(sample_data):
    kicks = np.flatnonzero(sample_data.actions == 0)
    with pytest.raises(ValueError, match="needs every class"):
        ReactionMemory.from_dataset(sample_data, kicks)


def test_the_sampler_starts_from_the_memory_of_the_training_subjects_only(tiny_model, leader, sample_data):  # noqa: F811
    model = ReactionModel.load(tiny_model)
    model.guidance = replace(model.guidance, memory_level=0.6)
    with pytest.raises(LabelError, match="reaction memory, and none is attached"):
        model.synthesize(leader, {"pushing": 1})
    model.attach_memory(sample_data)
    held_out = loso_fold(sample_data.subject_pairs, "s04").test
    assert len(model.memory.followers) == len(sample_data) - len(held_out)
    remembered = {m.tobytes() for m in model.memory.followers}
    assert not any(sample_data.canonical(int(i))[1].astype(np.float32).tobytes() in remembered for i in held_out)
    model.raw = True
    a = model.synthesize(leader, {"pushing": 1}, seed=0)
    assert np.isfinite(a).all() and np.array_equal(a, model.synthesize(leader, {"pushing": 1}, seed=0))
    steps = [model.synthesize(leader, {"pushing": v}, seed=0) for v in (1.0, 1.05, 1.10)]
    small = max(np.abs(steps[k + 1] - steps[k]).mean() for k in range(2))
    assert small < 0.2 * np.abs(model.synthesize(leader, {"pushing": 1.0}, seed=1) - a).mean()
    model.guidance = replace(model.guidance, memory_level=1.0)
    assert not np.allclose(model.synthesize(leader, {"pushing": 1}, seed=0), a)  # the memory changed the reaction


def test_generate_starts_from_the_memory_on_request(tiny_model, sample_data, tmp_path, capsys):  # noqa: F811
    from imm_model.cli import main

    sid = sample_data.sequence_ids[0]
    base = ["generate", "--checkpoint", str(tiny_model), "--sequence", sid, "--label", "hugging", "--raw"]
    assert main(base + ["--out", str(tmp_path / "noise.npz")]) == 0
    assert main(base + ["--memory", "0.4", "--out", str(tmp_path / "memory.npz")]) == 0
    noise, memory = (np.load(tmp_path / f)["follower"] for f in ("noise.npz", "memory.npz"))
    assert noise.shape == memory.shape and np.abs(noise - memory).mean() > 1e-3
    assert float(np.load(tmp_path / "memory.npz")["memory"]) == np.float32(0.4) and "memory" not in np.load(tmp_path / "noise.npz")
    capsys.readouterr()
    assert main(base + ["--memory", "2", "--out", str(tmp_path / "bad.npz")]) == 2
    err = capsys.readouterr().err
    assert "memory_level" in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "bad.npz").exists()
    gan = ["--checkpoint", str(SAMPLE_GAN)]
    assert main(["generate", *gan, "--sequence", sid, "--label", "hugging", "--memory", "0.5", "--out", str(tmp_path / "gan.npz")]) == 2
    assert "GAN" in capsys.readouterr().err and not (tmp_path / "gan.npz").exists()

