"""A label per body part: its spelling (`label_vector`, `Label.keys`), the sampler's part terms (`label_terms`), the
training rows that teach them (training/part_mix.py `part_rows`) and a part model end to end. Followers are the
bundled SBU data's; the sampler's network in the composition tests is a synthetic stand-in and the end-to-end model is
trained for a few steps only (their numbers are not results)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from imm_model.data.labels import Label, whole_body
from imm_model.errors import LabelError
from imm_model.families import load_model
from imm_model.families.diffusion.recipes import IMM_DIFFUSION, IMM_DIFFUSION_PARTS, DiffusionTrainConfig
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance, label_terms, sample
from imm_model.model.classifier import body_part_view
from imm_model.paths import SAMPLE_GAN
from imm_model.training.part_mix import part_indices, part_rows

C = 6
UPPER = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], np.float32)  # the stand-in's offset per class on the upper label
LOWER = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], np.float32)  # ... and on the lower label
COMPOSITE = 10.0  # the stand-in's own effect of a label naming another class on each part (not the sum of the parts)


def stand_in(x, step, leader_on, label, label_on):
    """x0 = the label's offsets, plus COMPOSITE when the upper and lower one-hots name different classes."""
    upper, lower = label[:, :C], label[:, C:]
    composite = (upper.sum(1) == 1) & (lower.sum(1) == 1) & ((upper != lower).any(1))
    out = ((upper * UPPER).sum(1) + (lower * LOWER).sum(1) + COMPOSITE * composite) * label_on
    return np.broadcast_to(out[:, None, None], x.shape).astype(np.float32).copy()


def composed(label: dict[str, float]) -> float:
    """The stand-in's reaction (one coordinate) for a part label, guidance 2 at the one step."""
    names = ["kicking", "pushing", "shaking_hands", "hugging", "exchanging_objects", "punching"]
    vec = np.zeros(2 * C, np.float32)
    for key, v in label.items():
        part, _, name = key.rpartition(":")
        for k in ((0, C) if not part else (0,) if part == "upper" else (C,)):
            vec[k + names.index(name)] = v
    leaders, mask, noise = np.zeros((1, 4, 45), np.float32), np.ones((1, 4), bool), np.zeros((1, 4, 45), np.float32)
    g = Guidance(label_scale=2.0, sample_steps=1, clip=100.0)  # no clamp at the stand-in's sizes
    return float(sample(stand_in, leaders, mask, vec[None], noise, g, 100, part_labels=True)[0, 0, 0])


def test_a_whole_body_label_is_the_condition_every_one_class_row_was_trained_on():
    assert np.isclose(composed({"pushing": 1}), 2.0 * (0.2 + 2.0))  # (e_c, e_c): both parts' offsets
    assert np.isclose(composed({"pushing": 0.5, "hugging": -1}), 2.0 * (0.5 * 2.2 - 4.4))  # the sum rule over classes


def test_a_part_alone_weighs_that_parts_condition():
    assert np.isclose(composed({"upper:pushing": 1}), 2.0 * 0.2)
    assert np.isclose(composed({"lower:hugging": -1}), -2.0 * 4.0)  # a part negation
    assert np.isclose(composed({"upper:shaking_hands": 1, "lower:pushing": -1}), 2.0 * (0.3 - 2.0))  # the paper's example


def test_two_classes_on_two_parts_are_guidance_on_the_composite_the_network_learned():
    assert np.isclose(composed({"upper:shaking_hands": 1, "lower:pushing": 1}), 2.0 * (0.3 + 2.0 + COMPOSITE))
    # the composite term enters continuously: a lower class at 0.01 moves the reaction by little
    assert abs(composed({"upper:shaking_hands": 1, "lower:pushing": 0.01}) - composed({"upper:shaking_hands": 1})) < 0.3


def test_a_part_split_moves_continuously_from_the_whole_body_label():
    whole = composed({"kicking": 1})
    assert abs(composed({"kicking": 1, "lower:kicking": 0.99}) - whole) < 0.05
    assert abs(composed({"kicking": 1, "lower:kicking": 1.01}) - whole) < 0.05


def test_label_terms_of_a_whole_label_network_are_unchanged_by_the_part_code():
    labels = np.array([[0, 1, 0, -0.5, 0, 0]], np.float32)
    conditions, weights = label_terms(labels)
    assert conditions.tolist() == [np.eye(C)[1].tolist(), np.eye(C)[3].tolist()]
    assert weights[:, 0].tolist() == [1.0, -0.5]
    assert label_terms(np.zeros((2, C), np.float32))[0].shape == (0, C)  # all zero: the label-free reaction alone


def test_the_join_gives_each_part_its_own_labels_prediction_at_every_step():
    """Guidance.part_join: a row whose parts differ follows, at every step, `join` of its upper part's prediction (each
    class as the whole-body condition) and its lower part's; a row whose parts agree is the whole-body label's, to the
    bit. With a join that keeps one side, the reaction is that side's whole-body label's, for a part network and a
    whole-label one alike."""
    rng = np.random.default_rng(0)
    leaders, mask = np.zeros((3, 5, 45), np.float32), np.ones((3, 5), bool)
    noise = rng.standard_normal((3, 5, 45)).astype(np.float32)
    g = Guidance(label_scale=2.0, sample_steps=4, clip=100.0)
    upper, lower = np.eye(C, dtype=np.float32)[[2, 0, 4]], np.eye(C, dtype=np.float32)[[1, 0, 3]] * -1
    lower[1] = upper[1]  # the second row's parts agree
    split = np.concatenate([upper, lower], 1)

    def network(part_labels):
        def whole_label(x, step, leader_on, label, label_on):  # a whole-label stand-in: the label's offsets per class
            return stand_in(x, step, leader_on, np.concatenate([label, label], 1), label_on)
        return (stand_in if part_labels else whole_label), (lambda v: np.concatenate([v, v], 1)) if part_labels else (lambda v: v)

    for part_labels in (True, False):
        net, whole = network(part_labels)
        keep_upper = sample(net, leaders, mask, split, noise, g, 100, part_labels=part_labels, join=lambda u, lo: u)
        keep_lower = sample(net, leaders, mask, split, noise, g, 100, part_labels=part_labels, join=lambda u, lo: lo)
        np.testing.assert_array_equal(keep_upper, sample(net, leaders, mask, whole(upper), noise, g, 100, part_labels=part_labels))
        by_lower = sample(net, leaders, mask, whole(lower), noise, g, 100, part_labels=part_labels)
        np.testing.assert_array_equal(keep_lower[[0, 2]], by_lower[[0, 2]])
        np.testing.assert_array_equal(keep_lower[1], keep_upper[1])  # parts alike: the whole-body label, whatever the join


def test_with_join_outputs_each_part_is_sampled_on_its_own_and_the_reactions_joined():
    """Guidance.join_outputs: a row whose parts differ is `join` of the upper part's whole reaction and the lower
    part's, each sampled from the same start as if asked alone; not the reaction joined at every step, which the
    network reads and pulls towards the other part's. A row whose parts agree is the whole-body label's, to the bit."""
    from dataclasses import replace

    from imm_model.families.diffusion.sampler import ddim, guided_prediction

    offsets = np.arange(1, C + 1, dtype=np.float32)

    def net(x, step, leader_on, label, label_on):  # reads x_t, not linearly, so that the trajectories matter
        return (np.tanh(2 * x) + ((label * offsets).sum(1) * label_on)[:, None, None]).astype(np.float32)

    def average(u, lo):
        return (u + lo) / 2

    rng = np.random.default_rng(1)
    leaders, mask = np.zeros((3, 5, 45), np.float32), np.ones((3, 5), bool)
    noise = rng.standard_normal((3, 5, 45)).astype(np.float32)
    upper, lower = np.eye(C, dtype=np.float32)[[2, 4, 0]], -np.eye(C, dtype=np.float32)[[1, 3, 0]]
    lower[2] = upper[2]  # the last row's parts agree
    g = Guidance(label_scale=2.0, sample_steps=4, clip=100.0, join_outputs=True)
    calls = []

    def counted(*args):
        calls.append(len(args[0]))
        return net(*args)

    apart = sample(counted, leaders, mask, np.concatenate([upper, lower], 1), noise, g, 100, join=average)
    assert len(calls) == g.sample_steps  # both parts' reactions side by side: one network call a step
    alone = [ddim(guided_prediction(net, v, g, 100, mask), noise, mask, g, 100) for v in (upper, lower)]
    np.testing.assert_allclose(apart[:2], average(*alone)[:2], atol=1e-6)
    np.testing.assert_array_equal(apart[2], sample(net, leaders, mask, upper, noise, g, 100)[2])
    every_step = sample(net, leaders, mask, np.concatenate([upper, lower], 1), noise, replace(g, join_outputs=False), 100,
                        join=average)
    assert not np.allclose(every_step[:2], apart[:2], atol=1e-3)
    np.testing.assert_array_equal(every_step[2], apart[2])


def test_the_bundled_default_takes_part_keys_through_its_samplers_join(sample_data):
    """The bundled diffusion model reads a whole-body label only; its sampler joins the parts (Guidance.part_join), so
    it takes a label per body part, and its whole-body reactions are those of the sampler without the join, to the bit."""
    from dataclasses import replace

    from imm_model.paths import SAMPLE_DIFFUSION

    model = load_model(SAMPLE_DIFFUSION)
    assert not model.config.part_labels and model.guidance.part_join and model.part_labels
    leader = sample_data.world(3)[0]
    whole = model.synthesize(leader, {"pushing": 1, "hugging": -0.5}, seed=2)
    split = model.synthesize(leader, {"upper:shaking_hands": 1, "lower:pushing": -1}, seed=2)
    model.guidance = replace(model.guidance, part_join=False)
    np.testing.assert_array_equal(model.synthesize(leader, {"pushing": 1, "hugging": -0.5}, seed=2), whole)
    with pytest.raises(LabelError, match=r"takes no label per body part \('upper:shaking_hands'\)"):
        model.label_vector({"upper:shaking_hands": 1, "lower:pushing": -1})
    assert split.shape == whole.shape and np.isfinite(split).all()
    for one in ({"shaking_hands": 1}, {"pushing": -1}):
        assert not np.allclose(split, model.synthesize(leader, one, seed=2))
    model.guidance = replace(model.guidance, part_join=True)  # the latent map's star: the part label's whole-body mean
    np.testing.assert_allclose(model.latent(leader, {"upper:shaking_hands": 1, "lower:pushing": -1}),
                               model.latent(leader, {"shaking_hands": 0.5, "pushing": -0.5}), atol=1e-6)


def test_the_samplers_join_composes_as_training_composes_real_followers(sample_data):
    """One composition for numpy arrays (the sampler) and torch tensors (training), the same numbers."""
    from imm_model.model.body_parts import compose_parts

    upper, _, centre = part_indices(sample_data.skeleton)
    a, b = (np.random.default_rng(k).standard_normal((2, 7, 15, 3)).astype(np.float32) for k in (1, 2))
    joined = compose_parts(a, b, upper, centre)
    assert isinstance(joined, np.ndarray) and not np.shares_memory(joined, b)
    np.testing.assert_allclose(joined, compose_parts(torch.from_numpy(a), torch.from_numpy(b), upper, centre).numpy(), atol=1e-6)


def test_a_part_config_is_refused_beside_pair_terms_and_its_recipe_needs_it():
    with pytest.raises(ValueError, match="part_labels"):
        DiffusionConfig(part_labels=True, pair_terms=True)
    with pytest.raises(ValueError, match="part_drop.*part_labels"):
        DiffusionTrainConfig.from_dict(IMM_DIFFUSION.to_dict() | {"part_drop": 0.3})
    assert DiffusionConfig.from_dict(IMM_DIFFUSION_PARTS.model).label_width == 2 * DiffusionConfig().num_classes


# ---- training rows ----------------------------------------------------------------------------------------------------
def test_part_rows_label_each_part_with_the_class_that_gave_it(sample_data):
    from imm_model.training.data import PaddedData

    rows = list(range(0, 197, 5))
    _, follower, lengths, actions = PaddedData.from_dataset(sample_data).batch(torch.as_tensor(rows))
    plain, both = part_rows(follower, lengths, actions, C, 0.0, 0.0, sample_data.skeleton, torch.Generator().manual_seed(0))
    one_hot = torch.nn.functional.one_hot(actions, C).float()
    assert torch.equal(plain, follower) and torch.equal(both, torch.cat([one_hot, one_hot], 1))  # one class on both parts

    mixed, labels = part_rows(follower, lengths, actions, C, 1.0, 0.0, sample_data.skeleton, torch.Generator().manual_seed(1))
    upper_class, lower_class = labels[:, :C].argmax(1), labels[:, C:].argmax(1)
    composite = upper_class != lower_class
    assert composite.any() and (labels.sum(1) == 2).all()
    assert ((upper_class == actions) | (lower_class == actions)).all()  # a row keeps its own class on one part
    assert (upper_class[composite] != actions[composite]).any() and (lower_class[composite] != actions[composite]).any()  # drawn
    upper, legs, _ = part_indices(sample_data.skeleton)
    for i in torch.nonzero(composite).flatten().tolist():  # its own part reads as its own follower's
        n = int(lengths[i])
        mine, got = follower[i, :n].unflatten(-1, (-1, 3)).numpy(), mixed[i, :n].unflatten(-1, (-1, 3)).numpy()
        if int(lower_class[i]) == int(actions[i]):
            assert np.allclose(got[:, legs], mine[:, legs])
        else:
            view = lambda x: body_part_view(x, "upper", sample_data.skeleton)  # noqa: E731
            assert np.allclose(view(got), view(mine), atol=1e-5)

    _, dropped = part_rows(follower, lengths, actions, C, 0.0, 1.0, sample_data.skeleton, torch.Generator().manual_seed(2))
    named = torch.stack([dropped[:, :C].sum(1), dropped[:, C:].sum(1)], 1)
    assert (named.sum(1) == 1).all() and (named[:, 0] == 1).any() and (named[:, 1] == 1).any()  # one part named, either


# ---- a part model end to end ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def part_model(tmp_path_factory, sample_data):
    """A part model trained for 20 steps at a small width (synthetic quality: only its plumbing is tested)."""
    from imm_model.families.diffusion.trainer import train

    cfg = DiffusionTrainConfig.from_dict(IMM_DIFFUSION_PARTS.to_dict() | {
        "steps": 20, "batch_size": 8, "checkpoint_every": 20,
        "model": IMM_DIFFUSION_PARTS.model | {"width": 32, "layers": 1, "heads": 2}})
    out = tmp_path_factory.mktemp("parts")
    torch.set_num_threads(1)
    train(cfg, sample_data, "s04", out, progress=False)
    return load_model(out / "final.safetensors")


def test_part_keys_parse_into_a_vector_per_part_and_back(part_model):
    names = part_model.class_names
    vec = part_model.label_vector({"shaking_hands": 1, "lower:shaking_hands": 0, "lower:pushing": -1}, scale=0.5)
    assert vec.shape == (2 * C,)
    assert Label.of(vec, names).keys() == {"upper:shaking_hands": 0.5, "lower:pushing": -0.5}
    assert part_model.label_vector({"kicking": 1}).shape == (C,)  # a whole-body label stays one value per class
    assert Label.of(part_model.label_vector({"kicking": 1, "upper:hugging": 1}), names).keys() == {"kicking": 1, "upper:hugging": 1}
    np.testing.assert_array_equal(part_model.label_vector(list(vec)), vec)  # 2C numbers: upper's, then lower's
    np.testing.assert_array_equal(whole_body(vec[None], C)[0], 0.5 * (vec[:C] + vec[C:]))


@pytest.mark.parametrize("label,words", [({"middle:kicking": 1}, "unknown class 'middle:kicking'"),
                                         ({"upper:kick": 1}, "unknown class 'upper:kick'"),
                                         ({"lower:pushing": 11}, "lower:pushing=11"),
                                         ([0.0] * 7, "expected 6 values .*or 12")])
def test_a_bad_part_label_is_refused_in_one_line(part_model, label, words):
    with pytest.raises(LabelError, match=words):
        part_model.label_vector(label)


def test_a_model_without_part_labels_refuses_a_part_key_naming_it():
    gan = load_model(SAMPLE_GAN)
    with pytest.raises(LabelError, match=r"takes no label per body part \('upper:shaking_hands'\)"):
        gan.label_vector({"upper:shaking_hands": 1})
    with pytest.raises(LabelError, match="expected 6 values"):
        gan.label_vector([0.0] * 12)


def test_a_part_model_synthesizes_whole_and_part_labels(part_model, sample_data, tmp_path):
    leader = sample_data.leader[sample_data.frames(3)]
    whole = part_model.synthesize(leader, {"pushing": 1}, seed=2)
    np.testing.assert_array_equal(whole, part_model.synthesize(leader, {"upper:pushing": 1, "lower:pushing": 1}, seed=2))
    split = part_model.synthesize(leader, {"upper:shaking_hands": 1, "lower:pushing": -1}, seed=2)
    assert split.shape == whole.shape and np.isfinite(split).all() and not np.allclose(split, whole)
    part_model.save(tmp_path / "again.safetensors")
    again = load_model(tmp_path / "again.safetensors")
    assert again.part_labels
    np.testing.assert_array_equal(again.synthesize(leader, {"upper:shaking_hands": 1, "lower:pushing": -1}, seed=2), split)
    twin = part_model.on_torch()
    np.testing.assert_allclose(twin.synthesize(leader, {"upper:shaking_hands": 1, "lower:pushing": -1}, seed=2), split, atol=1e-4)
    assert np.isfinite(part_model.latent(leader, {"upper:kicking": 1})).all()


def test_imm_generate_takes_part_keys_and_writes_them(part_model, sample_data, tmp_path, capsys):
    from imm_model.cli import main

    sid = sample_data.sequence_ids[3]
    out = tmp_path / "split.npz"
    assert main(["generate", "--checkpoint", str(part_model.path), "--sequence", sid, "--label",
                 "upper:shaking_hands=1,lower:pushing=-1", "--seed", "2", "--out", str(out)]) == 0
    assert "label upper:shaking_hands=1,lower:pushing=-1" in capsys.readouterr().out
    with np.load(out) as f:
        assert str(f["label_text"]) == "upper:shaking_hands=1,lower:pushing=-1" and f["label"].shape == (2 * C,)
        np.testing.assert_allclose(f["follower"], part_model.synthesize(
            f["leader"], {"upper:shaking_hands": 1, "lower:pushing": -1}, seed=2), atol=1e-4)
    assert main(["generate", "--checkpoint", str(SAMPLE_GAN), "--sequence", sid, "--label", "upper:shaking_hands=1",
                 "--out", str(tmp_path / "gan.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "takes no label per body part ('upper:shaking_hands')" in err[0]
