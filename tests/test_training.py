"""Training: recipes, schedule, determinism, exact resume, checkpoint safety, and that it learns."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.checkpoint import export_generator, final_checkpoint, load_checkpoint, save_checkpoint
from imm_model.cli import main
from imm_model.errors import CheckpointError
from imm_model.families import load_recipe
from imm_model.families.gan.recipes import IMM, PAPER, TrainConfig
from imm_model.families.gan.refit import refit
from imm_model.families.gan.schedule import adversarial_weight, lr_scale
from imm_model.families.gan.trainer import Trainer
from imm_model.inference import ReactionModel


def load_config(name_or_path: str, **overrides):
    return load_recipe(name_or_path, **overrides)[1]


TINY = replace(
    IMM,
    model=IMM.model | dict(stream_embed=16, encoder_hidden=8, decoder_hidden=16, attention_dim=8, disc_hidden=8, dropout=0.1),
    epochs=4, checkpoint_every=2, adv_warmup_epochs=1, adv_ramp_epochs=2, ema_decay=0.9, role_swap_prob=0.5,
    role_swap_classes=("hugging",),
)


def weights(trainer: Trainer) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in trainer.weights().items()}


def assert_same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def test_named_and_file_configs(tmp_path):
    assert load_config("paper") == PAPER and PAPER.optimizer == "rmsprop" and PAPER.batch_size == 16
    assert (PAPER.lambda_l1, PAPER.lambda_bone, PAPER.lambda_cont, PAPER.lambda_adv) == (1.0, 0.01, 1.0, 1.0)
    assert TrainConfig.from_dict(IMM.to_dict()) == IMM
    f = tmp_path / "r.json"
    f.write_text(json.dumps({"base": "paper", "epochs": 3}))
    cfg = load_config(str(f), seed=5)
    assert cfg.epochs == 3 and cfg.optimizer == "rmsprop" and cfg.seed == 5
    f.write_text(json.dumps({"epochz": 3}))
    with pytest.raises(ValueError, match="unknown training config keys"):
        load_config(str(f))
    with pytest.raises(ValueError, match="unknown config"):
        load_config("nope")
    for bad in ({"d_every": 0}, {"lr_decay_factor": 0}, {"lr_decay_patience": -1}, {"seed": -1}):
        f.write_text(json.dumps(bad))
        with pytest.raises(ValueError, match=f"training config: {next(iter(bad))} must be"):
            load_config(str(f))


def test_a_config_saved_before_options_were_retired_still_reads_and_resumes():
    """A config dict holding a retired option at the value that left it off reads as today's config and continues a
    run; one that switched it on is refused by name."""
    from imm_model.families.gan.recipes import RETIRED, same_recipe

    old = IMM.to_dict() | RETIRED
    assert TrainConfig.from_dict(old) == IMM
    assert same_recipe(old | {"epochs": 7}, IMM.to_dict()) and not same_recipe(old | {"seed": 3}, IMM.to_dict())
    for name, value in (("lambda_posture", 1.0), ("critic_seeds", [0, 1]), ("d_steps", 2)):
        with pytest.raises(ValueError, match=f"training config: {name} is no longer an option"):
            TrainConfig.from_dict(old | {name: value})
        assert not same_recipe(old | {name: value}, IMM.to_dict())


def test_adversarial_ramp():
    cfg = replace(IMM, lambda_adv=0.5, adv_warmup_epochs=2, adv_ramp_epochs=4)
    assert [adversarial_weight(cfg, e) for e in range(7)] == [0, 0, 0.125, 0.25, 0.375, 0.5, 0.5]


def test_learning_rate_decays_on_validation_plateaus():
    cfg = replace(IMM, lr_decay_patience=2, lr_decay_factor=0.5)
    vals = [9, 9, 5, 6, 7, 4, 5, 5, 5, 5]  # epochs 0-1 come before selection starts and are ignored
    history = [{"epoch": e, "val_afd_m": v} for e, v in enumerate(vals)]
    scales = [lr_scale(cfg, history[:n], select_from=2) for n in range(len(vals) + 1)]
    # plateaus of 2 epochs without a new best: after epoch 4 (6, 7 > 5) and after epochs 7 and 9 (5s > 4)
    assert scales == [1, 1, 1, 1, 1, 0.5, 0.5, 0.5, 0.25, 0.25, 0.125]
    assert lr_scale(IMM, history, select_from=2) == 1.0  # off by default


@pytest.mark.parametrize("step, decay", [(8, 0.5), (1000, 0.9)])  # TINY caps at 0.9
def test_ema_warm_up_window(sample_data, tmp_path, step, decay):
    trainer = Trainer(TINY, sample_data, "s04", tmp_path)
    with torch.no_grad():
        for p in trainer.G.parameters():
            p.fill_(1.0)
        for p in trainer.G_ema.parameters():
            p.zero_()
    trainer._update_ema(step)
    assert float(trainer.G_ema.out.weight[0, 0]) == pytest.approx(1 - decay)


@pytest.mark.slow
def test_refit_trains_on_training_and_validation_sequences(sample_data, tmp_path):
    cfg = replace(TINY, epochs=3, adv_warmup_epochs=0, adv_ramp_epochs=1, lr_decay_patience=1)
    selection = Trainer(cfg, sample_data, "s04", tmp_path / "sel")
    selection.fit(progress=False)
    assert final_checkpoint(selection.out) == selection.out / "best.safetensors"  # no refit yet
    path = refit(selection, progress=False)
    assert final_checkpoint(selection.out) == path == selection.out / "final.safetensors"
    tensors, meta = load_checkpoint(path)
    n_train, n_val = len(selection.train_idx), len(selection.val_idx)
    assert meta["refit"] == {"epochs": selection.state.best_epoch + 1, "sequences": n_train + n_val}
    assert meta["held_out_subject"] == "s04"  # the test subject is still never seen
    best, _ = load_checkpoint(selection.out / "best.safetensors")
    assert not torch.equal(tensors["generator.out.weight"], best["generator.out.weight"])
    again = refit(selection, progress=False)  # deterministic: an interrupted refit can simply be run again
    assert torch.equal(load_checkpoint(again)[0]["generator.out.weight"], tensors["generator.out.weight"])


def test_discriminator_updated_every_kth_batch(sample_data, tmp_path):
    trainer = Trainer(replace(TINY, d_every=3, adv_warmup_epochs=0, adv_ramp_epochs=0), sample_data, "s04", tmp_path)
    steps = []
    step = trainer.opt_d.step
    trainer.opt_d.step = lambda *a, **k: steps.append(1) or step(*a, **k)
    row = trainer.train_epoch(0)
    n_batches = -(-len(trainer.train_idx) // TINY.batch_size)
    assert len(steps) == -(-n_batches // 3)
    assert row["d_loss"] > 0 and 0 <= row["d_real_acc"] <= 1  # averaged over the batches that updated D


@pytest.mark.slow
def test_same_seed_same_weights_and_exact_resume(sample_data, tmp_path):
    straight = Trainer(TINY, sample_data, "s04", tmp_path / "a")
    straight.fit(progress=False)
    again = Trainer(TINY, sample_data, "s04", tmp_path / "b")
    again.fit(progress=False)
    assert_same(weights(straight), weights(again))

    first = Trainer(TINY, sample_data, "s04", tmp_path / "c")
    first.fit(epochs=2, progress=False)
    resumed = Trainer(TINY, sample_data, "s04", tmp_path / "c")
    resumed.resume()
    assert resumed.state.epoch == 2
    resumed.fit(progress=False)
    assert_same(weights(straight), weights(resumed))
    assert [r["epoch"] for r in resumed.state.history] == [0, 1, 2, 3]
    log = (tmp_path / "c" / "log.csv").read_text().splitlines()
    assert len(log) == 5 and (tmp_path / "c" / "curves.png").exists()

    other = Trainer(replace(TINY, seed=1), sample_data, "s04", tmp_path / "d")
    other.fit(epochs=1, progress=False)
    assert not torch.equal(other.G.out.weight, straight.G.out.weight)


@pytest.mark.slow
def test_short_training_lowers_validation_afd(sample_data, tmp_path):
    cfg = replace(IMM, model=TINY.model | {"decoder_hidden": 32}, epochs=12, lambda_adv=0.05, adv_warmup_epochs=4)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path)
    before = trainer.validate()["val_afd_m"]
    state = trainer.fit(progress=False)
    assert state.best_val < 0.8 * before
    assert any(r["adv"] > 0 for r in state.history)  # the adversarial term was on


@pytest.fixture(scope="module")
def checkpoint(sample_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("ck")
    trainer = Trainer(replace(TINY, epochs=1), sample_data, "s04", out)
    trainer.fit(progress=False)
    export_generator(out / "best.safetensors", out / "gen.safetensors")
    return out


def test_checkpoint_round_trip(checkpoint, sample_data):
    tensors, meta = load_checkpoint(checkpoint / "best.safetensors")
    assert meta["held_out_subject"] == "s04" and meta["class_names"] == list(sample_data.class_names)
    assert meta["skeleton"] == sample_data.skeleton.to_dict() and meta["canonical_mode"] == "first_frame"
    assert "code_version" in meta and "training" in meta
    model = ReactionModel.load(checkpoint / "gen.safetensors")
    assert not any(k.startswith("discriminator") for k in load_checkpoint(checkpoint / "gen.safetensors")[0])
    leader = sample_data.canonical(0)[0]
    full = ReactionModel.load(checkpoint / "best.safetensors")
    v = model.label_vector({"kicking": 1})
    assert (model.synthesize_canonical(leader, v) == full.synthesize_canonical(leader, v)).all()


def _one_line_error(path):
    with pytest.raises(CheckpointError) as err:
        ReactionModel.load(path)
    assert "\n" not in str(err.value) and path.stem in str(err.value)
    return str(err.value)


def test_corrupt_checkpoints_raise_one_line(checkpoint, tmp_path):
    src = (checkpoint / "gen.safetensors").read_bytes()
    side = (checkpoint / "gen.json").read_text()

    def write(name: str, data: bytes, sidecar: str | None = side):
        p = tmp_path / f"{name}.safetensors"
        p.write_bytes(data)
        if sidecar is not None:
            p.with_suffix(".json").write_text(sidecar)
        return p

    _one_line_error(write("truncated", src[: len(src) // 2]))
    _one_line_error(write("garbage", b"\x00\xff" * 500))
    _one_line_error(write("empty", b""))
    _one_line_error(tmp_path / "missing.safetensors")
    _one_line_error(write("badsidecar", src, "{not json"))
    # wrong architecture: the sidecar describes a bigger decoder than the weights
    meta = json.loads(side)
    meta["model_config"]["decoder_hidden"] = 64
    assert "shape" in _one_line_error(write("arch", src, json.dumps(meta)))
    # missing key
    tensors, meta = load_checkpoint(checkpoint / "gen.safetensors")
    del tensors["generator.out.weight"]
    save_checkpoint(tmp_path / "missing_key.safetensors", tensors, {k: v for k, v in meta.items() if k != "format"})
    assert "missing key" in _one_line_error(tmp_path / "missing_key.safetensors")


def test_cli_train_one_epoch_and_resume(tmp_path, capsys):
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(TINY.to_dict() | {"epochs": 1}))
    out = tmp_path / "run"
    assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(out), "--quiet",
                 "--export", str(tmp_path / "exp.safetensors")]) == 0
    assert (out / "fold-s04" / "best.safetensors").exists() and (tmp_path / "exp.json").exists()
    assert (out / "fold-s04" / "final.safetensors").exists()  # TINY inherits the shipped recipe's refit
    assert load_checkpoint(tmp_path / "exp.safetensors")[1]["refit"]["epochs"] == 1  # --export ships the refit
    assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(out), "--quiet", "--resume", "--epochs", "2"]) == 0
    assert "2 epochs" in capsys.readouterr().out
    assert main(["train", "--config", "paper", "--fold", "s99", "--out", str(out)]) == 2
    assert "s99" in capsys.readouterr().err


def test_cli_train_never_loses_work(tmp_path, capsys):
    """A finished run is never replaced without --overwrite; a refused command writes nothing; a run killed
    before its first checkpoint is not silently restarted by --resume; bad paths and numbers fail before training."""
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(TINY.to_dict() | {"epochs": 1, "refit": False}))
    out = tmp_path / "run"
    base = ["train", "--config", str(cfg), "--fold", "s04", "--out", str(out), "--quiet"]
    assert main(base) == 0
    best = (out / "fold-s04" / "best.safetensors").read_bytes()
    saved_config = (out / "config.json").read_text()
    assert main(base) == 2 and "--overwrite replaces it" in capsys.readouterr().err
    assert (out / "fold-s04" / "best.safetensors").read_bytes() == best
    other = tmp_path / "other.json"
    other.write_text(json.dumps(TINY.to_dict() | {"epochs": 1, "lr_g": 0.5}))
    assert main(["train", "--config", str(other), "--fold", "s04", "--out", str(out), "--quiet", "--resume"]) == 2
    assert "different config" in capsys.readouterr().err and (out / "config.json").read_text() == saved_config
    (out / "fold-s04" / "last.safetensors").unlink()  # as if killed before the first checkpoint
    assert main(base + ["--resume"]) == 2 and "no last.safetensors" in capsys.readouterr().err
    assert main(base + ["--overwrite"]) == 0
    for extra, message in ((["--threads", "0"], "--threads must be"), (["--epochs", "0"], "--epochs must be"),
                           (["--export", str(tmp_path / "missing" / "g.safetensors")], "not a writable directory"),
                           (["--export", str(cfg)], "expected a .safetensors")):
        assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(tmp_path / "new"), "--quiet"] + extra) == 2
        assert message in capsys.readouterr().err, extra
    assert not (tmp_path / "new").exists()  # nothing written by a refused command


def test_losses_that_stop_being_numbers_stop_training_naming_the_epoch(sample_data, tmp_path, capsys):
    """A follower frame at 1e30 (in memory: the readers refuse such files) or a learning rate that blows the weights up
    make the losses NaN: training stops at that epoch with one line, rc 2 from the CLI, and claims no checkpoint."""
    import copy

    from imm_model.errors import TrainingError

    poisoned = copy.deepcopy(sample_data)
    poisoned.follower[poisoned.frames(0).start + 3] = 1e30  # sequence 0 is a training sequence of fold s04
    with np.errstate(over="ignore", invalid="ignore"):  # the normalization's statistics overflow
        trainer = Trainer(replace(TINY, epochs=2), poisoned, "s04", tmp_path / "poisoned")
    with pytest.raises(TrainingError, match=r"training stopped at epoch 0: \w+ is nan"):
        trainer.fit(progress=False)
    assert not (tmp_path / "poisoned" / "best.safetensors").exists() and trainer.state.history == []
    cfg = tmp_path / "fast.json"
    cfg.write_text(json.dumps(TINY.to_dict() | {"epochs": 2, "lr_g": 1e30, "lr_d": 1e30, "ema_decay": 0.0}))
    out = tmp_path / "run"
    assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(out), "--quiet"]) == 2
    printed = capsys.readouterr()
    assert len(printed.err.strip().splitlines()) == 1 and "training stopped at epoch 0" in printed.err
    assert "best.safetensors" not in printed.out and not (out / "fold-s04" / "best.safetensors").exists()


def test_augmentation_keeps_skeletons_valid(sample_data):
    from imm_model.training.data import Augmenter, PaddedData

    perm = sample_data.skeleton.mirror_permutation
    assert [perm[perm[j]] for j in range(15)] == list(range(15)) and perm != list(range(15))
    padded = PaddedData.from_dataset(sample_data.subset(range(12)))
    idx = torch.arange(12)
    lengths = padded.lengths
    none = torch.zeros(6, dtype=torch.bool)
    aug = Augmenter(sample_data.skeleton, 1.0, 45.0, 0.0, none, time_warp=0.2, scale_jitter=0.0,
                    mirror_class_mask=torch.tensor([True, True, False, True, True, True]))
    leader, follower, new_lengths, actions = aug(padded, idx, torch.Generator().manual_seed(0))
    bones = torch.tensor(sample_data.skeleton.bones)
    from imm_model.families.gan.losses import bone_lengths

    for b in range(12):
        # rigid (mirror + yaw) transforms keep bone lengths (mirror swaps left/right bones, hence the sort);
        # time warp keeps the first and last frames
        before = bone_lengths(padded.leader[b : b + 1, [0, lengths[b] - 1]], bones).sort(-1).values
        after = bone_lengths(leader[b : b + 1, [0, new_lengths[b] - 1]], bones).sort(-1).values
        torch.testing.assert_close(before, after, atol=1e-4, rtol=1e-4)
        assert (leader[b, new_lengths[b]:] == 0).all()
    assert (new_lengths != lengths).any()


def test_label_free_baseline_ignores_the_label_and_trains(sample_data, tmp_path):
    """`--config men`: the generator never reads the label; D is a real/fake head beside a class head."""
    from imm_model.families.gan.numpy_generator import NumpyGenerator

    assert load_config("men").discriminator == "binary+class" and load_config("men").model["label_input"] is False
    cfg = replace(TINY, model=TINY.model | {"label_input": False}, discriminator="binary+class", adv_warmup_epochs=0,
                  adv_ramp_epochs=0)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path)
    row = trainer.train_epoch(0)
    assert row["adv"] > 0 and row["d_loss"] > 0 and all(map(torch.isfinite, map(torch.tensor, (row["adv"], row["d_loss"]))))
    G = trainer.G.eval()
    leader = torch.as_tensor(sample_data.canonical(0)[0].reshape(1, -1, 45))
    lengths = torch.tensor([leader.shape[1]])
    with torch.no_grad():
        a = G(leader, torch.eye(6)[:1], lengths)
        b = G(leader, -3 * torch.eye(6)[3:4], lengths)
    fast = NumpyGenerator({k: v.numpy() for k, v in G.state_dict().items()}, G.cfg)(leader[0].numpy(), np.eye(6)[0])
    assert torch.equal(a, b)
    np.testing.assert_allclose(fast, a[0], atol=1e-5, rtol=1e-4)
    with pytest.raises(ValueError, match="discriminator must be one of"):
        replace(TINY, discriminator="wasserstein")


@pytest.mark.parametrize("text, message", [
    ('{"lr_g": "fast"}', "lr_g must be a finite number"),
    ("[1, 2]", "a config is a JSON object"),
    ('{"model": 5}', "model must be a JSON object"),
    ('{"model": {"encoder_hidden": 1e9}}', "encoder_hidden must be an integer"),
    ('{"model": {"encoder_hidden": 100000}}', "encoder_hidden must be an integer in 1..4096"),
    ('{"model": {"dropout": "x"}}', "dropout must be a finite number"),
    ('{"epochs": -3}', "epochs must be an integer in 1..100000"),
    ('{"mirror_exclude_classes": [1]}', "a list of items, each a name"),
    ('{"a":' * 5000 + "1" + "}" * 5000, "nested too deeply"),
])
def test_bad_config_files_are_one_line_and_write_nothing(tmp_path, capsys, text, message):
    cfg = tmp_path / "c.json"
    cfg.write_text(text)
    assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


def test_role_swap_in_the_training_batches(sample_data):
    """The production path: with role_swap_prob 1 every hugging row of a batch is the pair with B leading,
    re-canonicalized on B (InteractionDataset.role_swapped, the one implementation); other classes unchanged."""
    from imm_model.training.data import Augmenter, PaddedData

    data = sample_data.subset(range(0, 197, 7))
    padded = PaddedData.from_dataset(data)
    hugging = torch.tensor([c == "hugging" for c in data.class_names])
    augment = Augmenter(data.skeleton, 0.0, 0.0, 1.0, hugging)
    idx = torch.arange(len(data))
    leader, follower, lengths, actions = augment(padded, idx, torch.Generator().manual_seed(0))
    swapped = data.role_swapped()
    hug = data.class_names.index("hugging")
    assert (actions == hug).any() and (actions != hug).any()
    for i in range(len(data)):
        t = int(lengths[i])
        a, b = swapped.canonical(i) if actions[i] == hug else data.canonical(i)
        torch.testing.assert_close(leader[i, :t], torch.as_tensor(a.reshape(t, -1)))
        torch.testing.assert_close(follower[i, :t], torch.as_tensor(b.reshape(t, -1)))


def test_late_starts_begin_mid_interaction_in_their_own_frame(sample_data):
    """A take's windows begin mid-interaction: the training rows that teach them are each pair from a later frame on,
    standardized from that frame (the leader's root at the origin there), as long as the pair goes on."""
    from imm_model.training.data import PaddedData, late_starts

    indices = np.array([0, 5])
    late = late_starts(sample_data, indices, 10)
    assert len(late) == sum(int(sample_data.lengths[i]) - 10 for i in indices)
    root = sample_data.skeleton.root
    for k in range(len(late)):
        leader, follower = late.canonical(k)
        assert np.abs(leader[0, root]).max() < 1e-4 and len(leader) >= 10
    first_world = sample_data.world(0)
    np.testing.assert_allclose(late.world(0)[1], first_world[1][1:], atol=1e-4)  # the same motion, from frame 1
    joined = PaddedData.joined(PaddedData.from_dataset(sample_data), PaddedData.from_dataset(late))
    assert len(joined.lengths) == len(sample_data) + len(late)
    assert int(joined.lengths[len(sample_data)]) == int(sample_data.lengths[0]) - 1
