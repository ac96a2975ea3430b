"""The reaction diffusion model: training, checkpoints, the sampler's label composition and seeds, the one API both
model families share. A tiny network trained for a few steps on the bundled SBU data (real data; the numbers it
produces are not results, only behaviour)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.checkpoint import load_checkpoint
from imm_model.cli import main
from imm_model.errors import LabelError, TrainingError
from imm_model.families import load_recipe
from imm_model.families.diffusion.denoiser import ReactionDenoiser, torch_denoiser
from imm_model.families.diffusion.denoiser_numpy import NumpyDenoiser
from imm_model.families.diffusion.model import DiffusionReactionModel
from imm_model.families.diffusion.recipes import IMM_DIFFUSION, DiffusionTrainConfig
from imm_model.families.diffusion.sampler import DiffusionConfig, Guidance, cosine_alpha_bar, initial_noise, sample, smoothed
from imm_model.families.diffusion.trainer import DiffusionTrainer
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_GAN

TINY = replace(IMM_DIFFUSION, name="tiny-diffusion", model=dict(width=16, layers=1, heads=2, ff_mult=1, dropout=0.0),
               guidance=dict(label_scale=2.5, sample_steps=4), steps=12, batch_size=8, warmup_steps=2, checkpoint_every=6,
               leader_noise_prob=0.0)  # a model that reads only the clean leader (the spread's tests train their own)


@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    from imm_model.data.dataset import InteractionDataset
    from imm_model.paths import SAMPLE_DATA

    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("diffusion")
    trainer = DiffusionTrainer(TINY, InteractionDataset.load(SAMPLE_DATA), "s04", out / "fold-s04")
    path = trainer.fit(progress=False)
    return path


@pytest.fixture(scope="module")
def leader(sample_data):
    return sample_data.world(0)[0]


def test_schedule_and_config_checks():
    alpha_bar = cosine_alpha_bar(100)
    assert alpha_bar.shape == (100,) and np.all(np.diff(alpha_bar) < 0) and 0 < alpha_bar[-1] < 0.01 < 0.99 < alpha_bar[0]
    for bad in ({"width": 30, "heads": 4}, {"layers": 0}, {"dropout": 1.0}, {"width": 10**6}):
        with pytest.raises(ValueError, match="diffusion config"):
            DiffusionConfig(**bad)
    for bad in ({"label_scale": -1.0}, {"sample_steps": 0}, {"clip": float("nan")}):
        with pytest.raises(ValueError, match="guidance"):
            Guidance(**bad)
    for bad in ({"label_drop": 1.0}, {"steps": 0}, {"family": "gan"}, {"seed": -1}):
        with pytest.raises(ValueError, match="training config"):
            replace(TINY, **bad)
    with pytest.raises(ValueError, match="unknown training config keys"):
        DiffusionTrainConfig.from_dict({"epochs": 3})


def test_adaln_blocks_start_as_identity():
    """Zero-initialized modulation: before training every block passes its input through, so depth costs nothing at
    the first step (DiT's adaLN-zero)."""
    net = ReactionDenoiser(DiffusionConfig(width=16, layers=3, heads=2)).eval()
    x = torch.randn(2, 7, 16)
    cond = torch.randn(2, 16)
    for block in net.blocks:
        assert torch.equal(block(x, cond, None), x)


@pytest.mark.parametrize("frames_per_token", [1, 2])
def test_every_frame_predicted_and_padding_ignored(frames_per_token):
    """An odd-length sequence keeps all its frames with two frames a token, and gives the same prediction alone as
    padded in a batch beside a longer one."""
    torch.manual_seed(0)
    net = ReactionDenoiser(DiffusionConfig(width=16, layers=2, heads=2, frames_per_token=frames_per_token)).eval()
    for block in net.blocks:  # away from the identity start, so that attention across frames matters
        torch.nn.init.normal_(block.modulation.weight, std=0.3)
    x, leader = torch.randn(2, 10, 45), torch.randn(2, 10, 45)
    mask = torch.arange(10)[None] < torch.tensor([[7], [10]])
    x, leader = x * mask[..., None], leader * mask[..., None]
    on, label = torch.tensor([True, True]), torch.eye(6)[:2]
    with torch.no_grad():
        batch = net(x, torch.tensor([50, 50]), leader, on, label, on, mask)
        alone = net(x[:1, :7], torch.tensor([50]), leader[:1, :7], on[:1], label[:1], on[:1])
    assert batch.shape == (2, 10, 45) and alone.shape == (1, 7, 45)
    assert torch.allclose(batch[0, :7], alone[0], atol=1e-5)


def test_trained_model_loads_as_the_diffusion_family(tiny_model):
    model = ReactionModel.load(tiny_model)
    assert isinstance(model, DiffusionReactionModel) and model.settings.seed and model.family == "diffusion"
    assert model.class_names[0] == "kicking" and model.guidance.sample_steps == 4
    meta = load_checkpoint(tiny_model)[1]
    assert meta["family"] == "diffusion" and meta["training"]["step"] == TINY.steps
    gan = ReactionModel.load(SAMPLE_GAN)
    assert not gan.settings.seed and gan.family == "gan"


def test_seeds_give_variations_and_repeat_exactly(tiny_model, leader):
    model = ReactionModel.load(tiny_model)
    a = model.synthesize(leader, {"kicking": 1}, seed=3)
    assert a.shape == leader.shape and a.dtype == np.float32 and np.isfinite(a).all()
    assert np.array_equal(a, model.synthesize(leader, {"kicking": 1}, seed=3))
    draws = model.synthesize(leader, {"kicking": 1}, seed=3, samples=4)
    assert draws.shape == (4, *leader.shape)
    assert np.allclose(draws[0], a, atol=1e-5)  # samples=N starts at `seed`
    spread = [np.abs(draws[0] - d).mean() for d in draws[1:]]
    assert min(spread) > 1e-3  # other seeds are other reactions


def test_smoothing_blends_each_follower_towards_savitzky_golay(tiny_model, leader):
    """Guidance.smoothing: `smoothed` is scipy's Savitzky-Golay filter (5 frames, order 2, ends fitted) at share 1 and
    the motion itself at 0; a model's raw follower at 0.3 is its follower at 0 blended so (the clean-up aside: the
    canonical-to-world move is rigid, so the blend commutes with it), with smaller frame-to-frame accelerations."""
    from scipy.signal import savgol_filter

    motion = np.random.default_rng(0).standard_normal((23, 15, 3)).astype(np.float32)
    assert np.allclose(smoothed(motion, 1.0), savgol_filter(motion.astype(np.float64), 5, 2, axis=0), atol=1e-5)
    assert smoothed(motion, 0.0) is motion and smoothed(motion[:4], 1.0) is not None
    assert np.array_equal(smoothed(motion[:4], 1.0), motion[:4])  # shorter than the window: as it is
    model = ReactionModel.load(tiny_model)
    model.raw = True
    plain = model.synthesize(leader, {"kicking": 1}, seed=0)
    model.guidance = replace(model.guidance, smoothing=0.3)
    blended = model.synthesize(leader, {"kicking": 1}, seed=0)
    assert np.allclose(blended, smoothed(plain, 0.3), atol=1e-4)
    accel = [np.abs(np.diff(m, 2, axis=0)).mean() for m in (plain, blended)]
    assert accel[1] < 0.9 * accel[0]
    with pytest.raises(ValueError, match="smoothing"):
        replace(model.guidance, smoothing=1.5)


@pytest.mark.parametrize("eta", [0.0, 0.5])
def test_a_moved_slider_moves_the_reaction_smoothly(tiny_model, leader, eta):
    """Same seed, label 1.0 -> 1.05 -> 1.10: the reaction changes by small, similar steps, far less than another
    seed changes it (DDIM is a continuous function of the label; with eta > 0 the seed fixes every step's noise too)."""
    model = ReactionModel.load(tiny_model)
    model.guidance = replace(model.guidance, eta=eta)
    model.raw = True  # the clean-up's foot planting is a threshold: judge the sampler's own output
    steps = [model.synthesize(leader, {"pushing": v}, seed=0) for v in (1.0, 1.05, 1.10)]
    small = [np.abs(steps[k + 1] - steps[k]).mean() for k in range(2)]
    other_seed = np.abs(model.synthesize(leader, {"pushing": 1.0}, seed=1) - steps[0]).mean()
    assert max(small) < 0.2 * other_seed and max(small) < 2.5 * min(small) + 1e-6


def test_signed_composition(tiny_model, sample_data):
    """All-zero labels are the leader-only term; -1 moves the other way from +1 (a negation), by the same amount after
    one step; the numpy and torch networks sample the same reaction."""
    model = ReactionModel.load(tiny_model)
    leader, mask = model._normalize_leaders([sample_data.canonical(0)[0]])
    noise = initial_noise(0, leader.shape[1], 45)[None]
    one_step = replace(model.guidance, sample_steps=1)
    label = lambda v: np.array([[0, v, 0, 0, 0, 0]], np.float32)  # noqa: E731
    denoise = model._denoiser(leader, mask)
    base, plus, minus = (sample(denoise, leader, mask, label(v), noise, one_step, 100) for v in (0.0, 1.0, -1.0))
    assert np.allclose(plus - base, base - minus, atol=1e-4) and np.abs(plus - base).mean() > 1e-4
    on_torch = sample(torch_denoiser(model.net, leader, mask), leader, mask, label(1.0), noise, model.guidance, 100)
    assert np.allclose(on_torch, sample(denoise, leader, mask, label(1.0), noise, model.guidance, 100), atol=1e-4)


def test_eta_zero_is_plain_ddim():
    """eta 0 (the default, which checkpoints without an eta get) is the deterministic DDIM update, checked against
    that update written out here on a synthetic linear denoiser; seeds play no part in it."""
    rng = np.random.default_rng(0)
    noise, leaders = rng.standard_normal((2, 3, 9, 6)).astype(np.float32)
    mask = np.arange(9)[None] < np.array([[9], [5], [7]])
    noise *= mask[..., None]
    denoise = lambda x, step, *_: 0.6 * x + 0.01 * step  # noqa: E731 - synthetic x0 prediction
    guidance = Guidance(sample_steps=5)
    assert Guidance.from_dict({"label_scale": 2.5}).eta == 0.0
    alpha_bar, steps = cosine_alpha_bar(100), np.linspace(99, 0, 5).round().astype(int)
    x = noise.copy()
    for i, step in enumerate(steps[:-1]):
        x0 = np.clip(denoise(x, step), -6, 6) * mask[..., None]
        a, a_next = alpha_bar[step], alpha_bar[steps[i + 1]]
        eps = (x - np.sqrt(a) * x0) / np.sqrt(1 - a)
        x = ((np.sqrt(a_next) * x0 + np.sqrt(1 - a_next) * eps) * mask[..., None]).astype(np.float32)
    expected = np.clip(denoise(x, 0), -6, 6) * mask[..., None]
    labels = np.zeros((3, 6), np.float32)
    got = sample(denoise, leaders, mask, labels, noise, guidance, 100)
    assert np.allclose(got, expected, atol=1e-6)
    assert np.array_equal(got, sample(denoise, leaders, mask, labels, noise, guidance, 100, seeds=[4, 5, 6]))


def test_guidance_in_a_limited_interval():
    """guided_below: above that noise level every class term weighs its label value alone (s = 1), below it s. On a
    synthetic denoiser whose class term adds a fixed offset, guided only at the last step the reaction is the s = 1
    one plus (s - 1) times the offset; guided at every step (the default, 1) it is the plain guided one."""
    rng = np.random.default_rng(0)
    noise, leaders = rng.standard_normal((2, 2, 9, 6)).astype(np.float32)
    mask = np.ones((2, 9), bool)
    offset = np.float32(0.05) * np.arange(6, dtype=np.float32)

    def denoise(x, step, leader_on, label, label_on):  # synthetic x0 prediction: the class term adds `offset`
        return 0.6 * x + 0.01 * step + (label_on[:, None] * label)[:, :1, None] * offset

    labels = np.array([[1, 0, 0, 0, 0, 0], [0.5, 0, 0, 0, 0, 0]], np.float32)
    run = lambda **g: sample(denoise, leaders, mask, labels, noise, Guidance(sample_steps=5, **g), 100)  # noqa: E731
    plain = run(label_scale=1.0)
    last_only = run(label_scale=2.5, guided_below=0.0)
    assert np.allclose(last_only - plain, 1.5 * labels[:, :1, None] * offset, atol=1e-5)
    assert np.array_equal(run(label_scale=2.5), run(label_scale=2.5, guided_below=1.0))
    middle = run(label_scale=2.5, guided_below=0.5)
    assert not np.allclose(middle, last_only, atol=1e-4) and not np.allclose(middle, run(label_scale=2.5), atol=1e-4)
    with pytest.raises(ValueError, match="guided_below"):
        Guidance(guided_below=1.5)


def test_the_leader_conditions_below_a_noise_level_only():
    """leader_below: the steps above that noise level see every term's leader absent, the others see it present (but
    the unconditioned term of a leader scale != 1); the default, 1, conditions every step on the leader."""
    rng = np.random.default_rng(0)
    noise, leaders = rng.standard_normal((2, 2, 9, 6)).astype(np.float32)
    mask = np.ones((2, 9), bool)
    labels = np.array([[1, 0, 0, 0, 0, 0], [0, 0, -1, 0, 0, 0]], np.float32)
    seen: list[tuple[int, np.ndarray]] = []

    def denoise(x, step, leader_on, label, label_on):  # synthetic: the leader term adds 0.1
        seen.append((step, leader_on.copy()))
        return 0.6 * x + 0.1 * leader_on[:, None, None]

    def run(**g):
        seen.clear()
        out = sample(denoise, leaders, mask, labels, noise, Guidance(sample_steps=5, **g), 100)
        return out, [(step, bool(on.any()), bool(on.all())) for step, on in seen]

    everywhere, steps = run()
    assert [s for s, _, _ in steps] == [99, 74, 50, 25, 0] and all(all_on for _, _, all_on in steps)
    assert np.array_equal(everywhere, run(leader_below=1.0)[0])
    late, steps = run(leader_below=0.6)  # 74 / 99 > 0.6 >= 50 / 99
    assert [any_on for _, any_on, _ in steps] == [False, False, True, True, True]
    assert not np.allclose(late, everywhere, atol=1e-4)
    _, steps = run(leader_below=0.6, leader_scale=2.0)
    assert [(any_on, all_on) for _, any_on, all_on in steps][2:] == [(True, False)] * 3  # the unconditioned term stays off
    with pytest.raises(ValueError, match="leader_below"):
        Guidance(leader_below=-0.1)


def test_stochastic_steps_follow_the_seed(tiny_model, sample_data):
    """eta > 0: the same seed repeats exactly, alone or in a batch beside a longer sequence; with the starting noise
    held fixed another seed still gives another reaction (the steps' noise is the seed's), where eta 0 gives the same
    one; a row without a seed is refused."""
    model = ReactionModel.load(tiny_model)
    short, long = sample_data.canonical(0)[0], sample_data.canonical(1)[0]
    assert len(short) != len(long)
    x, mask = model._normalize_leaders([short, long])
    label = np.array([[0, 1, 0, 0, 0, 0]] * 2, np.float32)
    noise = np.stack([initial_noise(0, x.shape[1], 45)] * 2) * mask[..., None]
    denoise = model._denoiser(x, mask)
    run = lambda eta, seeds: sample(denoise, x, mask, label, noise, replace(model.guidance, eta=eta), 100, seeds=seeds)  # noqa: E731
    a = run(0.5, [3, 3])
    assert np.array_equal(a, run(0.5, [3, 3]))
    alone_x, alone_mask = model._normalize_leaders([short])
    alone = sample(model._denoiser(alone_x, alone_mask), alone_x, alone_mask, label[:1], noise[:1, : len(short)],
                   replace(model.guidance, eta=0.5), 100, seeds=[3])
    assert np.allclose(alone[0], a[0, : len(short)], atol=1e-5)
    assert np.array_equal(run(0.0, [3, 3]), run(0.0, [4, 4]))
    assert np.abs(run(0.5, [4, 4]) - a)[mask].mean() > 1e-3
    with pytest.raises(ValueError, match="one seed per row"):
        run(0.5, None)


@pytest.mark.parametrize("frames_per_token, leader_noise", [(1, False), (2, False), (1, True)])
def test_numpy_denoiser_matches_torch(frames_per_token, leader_noise):
    torch.manual_seed(1)
    cfg = DiffusionConfig(width=16, layers=2, heads=2, frames_per_token=frames_per_token, leader_noise=leader_noise)
    net = ReactionDenoiser(cfg).eval()
    for block in net.blocks:
        torch.nn.init.normal_(block.modulation.weight, std=0.3)
    state = {k: v.numpy() for k, v in net.state_dict().items()}
    assert {k: v.shape for k, v in state.items()} == NumpyDenoiser.expected_shapes(cfg)
    fast = NumpyDenoiser(state, cfg)
    x, leader = np.random.default_rng(0).standard_normal((2, 2, 9, 45)).astype(np.float32)
    mask = np.arange(9)[None] < np.array([[9], [6]])
    on, label = np.array([True, False]), np.eye(6, dtype=np.float32)[:2]
    levels = np.array([40.0, 0.0], np.float32)
    with torch.no_grad():
        ref = net(*map(torch.as_tensor, (x, np.array([30, 30]), leader, on, label, on[::-1].copy(), mask)),
                  leader_level=torch.as_tensor(levels)).numpy()
        clean = net(*map(torch.as_tensor, (x, np.array([30, 30]), leader, on, label, on[::-1].copy(), mask))).numpy()
    assert np.allclose(fast(x, 30, leader, on, label, on[::-1].copy(), mask, leader_level=levels)[mask], ref[mask], atol=1e-5)
    # the leader's noise level enters the prediction only where the network reads it
    assert np.allclose(ref, clean) != leader_noise


@pytest.mark.parametrize("frames_per_token", [1, 2])
def test_conditioned_denoiser_reused_across_steps_matches_torch(frames_per_token):
    """The leader's and the label's share computed once and reused for several steps (one of them met twice, from
    the step cache) gives the torch module's prediction at each step (random weights and inputs)."""
    torch.manual_seed(2)
    cfg = DiffusionConfig(width=16, layers=2, heads=2, frames_per_token=frames_per_token)
    net = ReactionDenoiser(cfg).eval()
    for block in net.blocks:
        torch.nn.init.normal_(block.modulation.weight, std=0.3)
    fast = NumpyDenoiser({k: v.numpy() for k, v in net.state_dict().items()}, cfg)
    rng = np.random.default_rng(1)
    leader = rng.standard_normal((3, 9, 45)).astype(np.float32)
    mask = np.arange(9)[None] < np.array([[9], [5], [8]])
    on, label = np.array([True, True, False]), np.eye(6, dtype=np.float32)[[0, 3, 5]] * np.float32(0.7)
    label_on = np.array([False, True, True])
    conditioned = fast.conditioned(leader, on, label, label_on, mask)
    for step in (99, 40, 99, 0):
        x = rng.standard_normal((3, 9, 45)).astype(np.float32)
        with torch.no_grad():
            ref = net(*map(torch.as_tensor, (x, np.full(3, step), leader, on, label, label_on, mask))).numpy()
        assert np.allclose(conditioned(x, step)[mask], ref[mask], atol=1e-5)


def test_attention_softmax_with_and_without_the_max_shift():
    """The numpy attention skips the softmax's max shift only where every score is small: with small and with large
    scores (random queries scaled up until exp would overflow), and padded keys, it equals a float64 softmax."""
    from imm_model.families.diffusion.denoiser_numpy import _attention

    rng = np.random.default_rng(0)
    q, k, v = rng.standard_normal((3, 2, 2, 7, 4)).astype(np.float32)
    pad = np.where(np.arange(7) < np.array([[7], [4]]), 0.0, -np.inf).astype(np.float32)[:, None, :, None]
    for scale in (1.0, 60.0):  # scores within +-7; within +-380, past the shift-free range
        scores = (q * scale).astype(np.float64) @ k.swapaxes(-1, -2) + pad.swapaxes(-1, -2)
        weights = np.exp(scores - scores.max(-1, keepdims=True))
        ref = weights / weights.sum(-1, keepdims=True) @ v
        out = _attention(q * np.float32(scale), k, v, pad)
        assert np.isfinite(out).all() and np.allclose(out, ref, atol=1e-4), scale


def test_the_models_network_call_conditions_once_per_set_of_terms(tiny_model, sample_data):
    """`sample`'s network call conditions on the leaders once per set of terms: a call with other terms, and the first
    terms again, each give what the network gives for them afresh."""
    model = ReactionModel.load(tiny_model)
    x, mask = model._normalize_leaders([sample_data.canonical(0)[0], sample_data.canonical(1)[0]])
    denoise = model._denoiser(x, mask)
    rng = np.random.default_rng(0)
    terms = [(np.ones(4, bool), np.eye(6, dtype=np.float32)[[0, 0, 2, 2]], np.array([False, False, True, True])),
             (np.array([True, True, False, False]), np.zeros((4, 6), np.float32), np.zeros(4, bool))]
    for leader_on, label, label_on in (*terms, terms[0]):
        x_t = rng.standard_normal((4, *x.shape[1:])).astype(np.float32)
        fresh = model.fast(x_t, 50, np.tile(x, (2, 1, 1)), leader_on, label, label_on, np.tile(mask, (2, 1)))
        assert np.allclose(denoise(x_t, 50, leader_on, label, label_on), fresh, atol=1e-6)


def test_resume_continues_exactly(sample_data, tmp_path):
    cfg = replace(TINY, steps=8, checkpoint_every=4)
    whole = DiffusionTrainer(cfg, sample_data, "s04", tmp_path / "whole")
    whole.fit(progress=False)
    half = DiffusionTrainer(cfg, sample_data, "s04", tmp_path / "half")
    for _ in range(4):  # as if killed right after the checkpoint at step 4
        half.train_step()
    half.save_last()
    resumed = DiffusionTrainer(cfg, sample_data, "s04", tmp_path / "half")
    resumed.resume()
    assert resumed.step == 4
    resumed.fit(progress=False)
    a = load_checkpoint(tmp_path / "whole" / "final.safetensors")[0]
    b = load_checkpoint(tmp_path / "half" / "final.safetensors")[0]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_non_finite_loss_stops_training(sample_data, tmp_path):
    import copy

    poisoned = copy.deepcopy(sample_data)
    poisoned.follower[poisoned.frames(0).start + 3] = 1e30
    with pytest.raises(TrainingError, match=r"before step 0: a training joint 1e\+30 m"):
        DiffusionTrainer(replace(TINY, steps=3), poisoned, "s04", tmp_path / "poisoned")
    blown = DiffusionTrainer(replace(TINY, steps=3, lr=1.0, warmup_steps=0), sample_data, "s04", tmp_path / "blown")
    for p in blown.net.parameters():  # weights already beyond float range: the first loss is not a number
        p.data.fill_(1e38)
    with pytest.raises(TrainingError, match="not finite at step 0"):
        blown.fit(progress=False)
    assert not (tmp_path / "poisoned").exists() and not (tmp_path / "blown" / "final.safetensors").exists()


def test_seed_and_samples_checked_in_one_line(tiny_model, leader):
    model = ReactionModel.load(tiny_model)
    for kwargs, message in (({"seed": -1}, "seed must be"), ({"seed": 1.5}, "seed must be"), ({"samples": 0}, "samples must be"),
                            ({"samples": 10_000}, "samples must be"), ({"seed": 2**31 - 1, "samples": 2}, "runs past")):
        with pytest.raises(LabelError, match=message):
            model.synthesize(leader, {"kicking": 1}, **kwargs)


def test_the_gan_answers_the_same_api_with_one_reaction(leader):
    gan = ReactionModel.load(SAMPLE_GAN)
    draws = gan.synthesize(leader, {"kicking": 1}, seed=5, samples=3)
    assert draws.shape == (3, *leader.shape) and np.array_equal(draws[0], draws[2])
    assert np.array_equal(draws[0], gan.synthesize(leader, {"kicking": 1}))


def test_latent_embeddings(tiny_model, sample_data):
    model = ReactionModel.load(tiny_model)
    leaders = [sample_data.canonical(i)[0] for i in range(3)]
    z = model.latent_canonical_batch(leaders, np.eye(6, dtype=np.float32)[:3])
    assert z.shape == (3, 16) and np.isfinite(z).all()


def test_cli_trains_a_diffusion_recipe(tmp_path, capsys):
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps({"base": "imm-diffusion", "model": TINY.model, "guidance": TINY.guidance, "steps": 3,
                               "batch_size": 4, "checkpoint_every": 2}))
    assert [load_recipe(name)[0].name for name in (str(cfg), "imm-diffusion", "imm-steer")] == ["diffusion", "diffusion", "gan"]
    out = tmp_path / "run"
    base = ["train", "--config", str(cfg), "--fold", "s04", "--out", str(out), "--quiet"]
    assert main(base + ["--export", str(tmp_path / "exp.safetensors")]) == 0
    assert "3 steps" in capsys.readouterr().out
    exported = ReactionModel.load(tmp_path / "exp.safetensors")
    assert isinstance(exported, DiffusionReactionModel)
    assert main(base + ["--resume", "--steps", "4"]) == 0
    assert load_checkpoint(out / "fold-s04" / "final.safetensors")[1]["training"]["step"] == 4
    assert main(base + ["--overwrite", "--epochs", "2"]) == 2
    assert "--epochs does not apply" in capsys.readouterr().err


def test_generate_draws_variations_with_seeds(tiny_model, sample_data, tmp_path, capsys):
    sid = sample_data.sequence_ids[0]
    out = tmp_path / "variations"
    base = ["generate", "--checkpoint", str(tiny_model), "--sequence", sid, "--label", "hugging"]
    assert main(base + ["--samples", "3", "--seed", "5", "--out", str(out)]) == 0
    files = sorted(out.iterdir())
    assert [f.name.rsplit("_", 1)[1] for f in files] == ["seed5.npz", "seed6.npz", "seed7.npz"]
    followers = [np.load(f)["follower"] for f in files]
    assert np.abs(followers[0] - followers[1]).mean() > 1e-3
    one = tmp_path / "one.npz"
    assert main(base + ["--seed", "6", "--out", str(one)]) == 0
    assert np.allclose(np.load(one)["follower"], followers[1], atol=1e-5)  # a seed is the same reaction wherever drawn
    assert [int(np.load(f)["seed"]) for f in files] == [5, 6, 7] and int(np.load(one)["seed"]) == 6  # the file says which
    gan = ["--checkpoint", str(SAMPLE_GAN)]
    assert main(["generate", *gan, "--sequence", sid, "--label", "hugging", "--out", str(tmp_path / "gan.npz")]) == 0
    assert "seed" not in np.load(tmp_path / "gan.npz")  # a deterministic model's file names no seed
    capsys.readouterr()
    assert main(["generate", *gan, "--sequence", sid, "--label", "hugging", "--samples", "2", "--out", str(tmp_path / "gan")]) == 2
    assert "deterministic" in capsys.readouterr().err and not (tmp_path / "gan").exists()
    assert main(base + ["--samples", "0", "--out", str(tmp_path / "none")]) == 2
    assert "samples must be" in capsys.readouterr().err


@pytest.mark.slow
def test_evaluation_reports_a_stochastic_models_variations_and_mixed_readings(tiny_model, sample_data, tmp_path, monkeypatch):
    from imm_model.evaluation.loso import EvalOptions, evaluate_fold
    from imm_model.model.classifier_config import ClassifierConfig

    monkeypatch.setenv("IMM_CACHE_DIR", str(tmp_path / "cache"))
    quick = {"epochs": 2, "hidden": 16, "features": 8}
    judges = {name: ClassifierConfig.from_dict(getattr(EvalOptions, name).to_dict() | quick)
              for name in ("interaction", "follower", "judge", "upper", "lower")}
    result = evaluate_fold(ReactionModel.load(tiny_model), sample_data, "s04",
                           EvalOptions(baselines=("nn1",), progress=False, **judges))
    v = result["variations"]
    assert v["samples"] == 5 and v["afd_best_of_n"] <= v["afd_single"] and v["multimodality"] > 0 < v["multimodality_m"]
    assert v["real_class_diversity"] > 0 < v["real_same_leader_diversity"]
    rows = result["mix_parts"]
    assert len(rows) == 15 and all(max(r["whole"], r["parts"]) <= r["mixed"] <= r["whole"] + r["parts"] + 1e-9 for r in rows)
    # the whole-body judge's reading of real mixed motion, held-out part composites: a share, on every pair (s04 holds
    # followers of every class)
    assert all(0 <= r["real_whole"] <= 1 for r in rows)
    assert 0 <= result["avoid_judge"]["share_lowered"] <= 1
    gan = evaluate_fold(ReactionModel.load(SAMPLE_GAN), sample_data, "s04",
                        EvalOptions(baselines=("nn1",), progress=False, **judges))
    assert "variations" not in gan and len(gan["mix_parts"]) == 15

    from imm_model.evaluation.report import FoldFigures  # what `imm reproduce --tables models` tabulates
    from imm_model.reproduce.jobs import TrainJob
    from imm_model.reproduce.report import models_section
    from imm_model.reproduce.tasks import EvalJob

    typed = FoldFigures.of(result)
    figures = typed.flat()
    assert typed.nn1 is not None and typed.afd_best_of_n == figures["afd_best_of_n"] and figures["afd_nn1"] == typed.nn1.afd
    assert figures["fid"] == result["model"]["fid"] and figures["afd_best_of_n"] == v["afd_best_of_n"]
    assert 0 <= figures["mixed_worst_pair"] <= figures["mixed"] <= 1 and "fid_nn1_hugging" in figures
    assert "multimodality_ratio" not in FoldFigures.of(gan).flat() and FoldFigures.of(gan).multimodality_ratio is None
    assert 0 <= figures["classes_beyond_real_contact"] <= 6
    assert figures["contact_ratio_worst_class"] <= 1.25 or figures["classes_beyond_real_contact"] >= 1
    results = {EvalJob(TrainJob(r, "s04", 0), "final", baselines=("nn1",)): res
               for r, res in (("imm-steer", gan), ("imm-diffusion", result))}
    table = models_section(results, list(sample_data.class_names))
    assert "imm-steer, dev folds (1 runs)" in table and "imm-diffusion, dev folds (1 runs)" in table and "test folds (" not in table
    cells = next(line for line in table.splitlines() if line.startswith("| variations")).split("|")
    assert cells[2].strip() == "-" and cells[3].strip() == f"{figures['multimodality_ratio']:.2f}"
    hugging = [FoldFigures.of(gan).fid_per_class["hugging"], figures["fid_hugging"], figures["fid_nn1_hugging"]]
    assert "| hugging | " + " | ".join(f"{x:.2f}" for x in hugging) + " |" in table


@pytest.mark.parametrize("override, message", [({"lr": -1}, "lr must be"), ({"model": {"width": 30, "heads": 4}}, "width must be"),
                                               ({"guidance": 5}, "guidance must be a JSON object"),
                                               ({"steps": "many"}, "steps must be"), ({"epochs": 3}, "unknown training config keys")])
def test_a_bad_diffusion_recipe_is_one_line_and_trains_nothing(tmp_path, capsys, override, message):
    cfg = tmp_path / "bad.json"
    cfg.write_text(json.dumps({"base": "imm-diffusion"} | override))
    assert main(["train", "--config", str(cfg), "--fold", "s04", "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err, err
    assert not (tmp_path / "run").exists()


@pytest.fixture(scope="module")
def leader_noise_model(tmp_path_factory):
    from imm_model.data.dataset import InteractionDataset
    from imm_model.paths import SAMPLE_DATA

    torch.set_num_threads(1)
    cfg = replace(TINY, model=TINY.model | {"leader_noise": True}, leader_noise_prob=0.5)
    trainer = DiffusionTrainer(cfg, InteractionDataset.load(SAMPLE_DATA), "s04", tmp_path_factory.mktemp("noised") / "fold-s04")
    return trainer.fit(progress=False)


def test_a_noised_leader_widens_the_variations_and_follows_the_seed(leader_noise_model, tiny_model, leader):
    """With Guidance.leader_noise the network sees its leader through noise drawn from the seed: the same seed repeats
    exactly, the reaction differs from the clean leader's, and a moved slider still moves it smoothly. A model trained
    on clean leaders only refuses the setting in one line."""
    model = ReactionModel.load(leader_noise_model)
    model.raw = True
    clean = model.synthesize(leader, {"kicking": 1}, seed=3)
    model.guidance = replace(model.guidance, leader_noise=0.6)
    noised = model.synthesize(leader, {"kicking": 1}, seed=3)
    assert np.array_equal(noised, model.synthesize(leader, {"kicking": 1}, seed=3))
    assert np.abs(noised - clean).mean() > 1e-3
    steps = [model.synthesize(leader, {"kicking": v}, seed=3) for v in (1.0, 1.05, 1.10)]
    small = [np.abs(steps[k + 1] - steps[k]).mean() for k in range(2)]
    other_seed = np.abs(model.synthesize(leader, {"kicking": 1.0}, seed=4) - steps[0]).mean()
    assert max(small) < 0.2 * other_seed
    plain = ReactionModel.load(tiny_model)
    plain.guidance = replace(plain.guidance, leader_noise=0.6)
    with pytest.raises(LabelError, match="leader noise 0.6 needs a model trained with noised leaders"):
        plain.synthesize(leader, {"kicking": 1}, seed=3)


def test_the_last_step_reads_the_clean_leader(leader_noise_model, leader, monkeypatch):
    """With a spread, every sampler step but the last sees the noised leader and is told its level; the last step, whose
    prediction is the output, sees the clean leader (else the leader's noise shows in the reaction as jitter)."""
    model = ReactionModel.load(leader_noise_model)
    model.spread = 0.6
    seen, network = [], model._denoiser

    def spy(leaders, mask, leader_level=0):
        call = network(leaders, mask, leader_level)

        def denoise(x_t, step, *terms):
            seen.append((step, leader_level, leaders.copy()))
            return call(x_t, step, *terms)
        return denoise

    monkeypatch.setattr(model, "_denoiser", spy)
    model.synthesize(leader, {"kicking": 1}, seed=3)
    steps = [step for step, _, _ in seen]
    assert steps == sorted(steps, reverse=True) and steps[-1] == 0 and len(steps) == model.guidance.sample_steps
    assert [level for _, level, _ in seen] == [round(0.6 * 99)] * (len(steps) - 1) + [0]  # 0.6 of steps 0..99, then clean
    noised, clean = seen[0][2], seen[-1][2]
    assert np.abs(noised - clean).mean() > 0.1


def test_noised_leader_training_needs_the_network_that_reads_the_level():
    with pytest.raises(ValueError, match="leader_noise_prob must be 0 unless model.leader_noise is true"):
        replace(TINY, leader_noise_prob=0.5)


def test_generate_takes_a_spread_and_the_file_records_it(leader_noise_model, tiny_model, sample_data, tmp_path, capsys):
    sid = sample_data.sequence_ids[0]
    base = ["generate", "--sequence", sid, "--label", "hugging", "--seed", "2"]
    assert main(base + ["--checkpoint", str(leader_noise_model), "--spread", "0.5", "--out", str(tmp_path / "loose.npz")]) == 0
    assert main(base + ["--checkpoint", str(leader_noise_model), "--spread", "0", "--out", str(tmp_path / "close.npz")]) == 0
    loose, close = np.load(tmp_path / "loose.npz"), np.load(tmp_path / "close.npz")
    assert float(loose["spread"]) == 0.5 and float(close["spread"]) == 0.0
    assert np.abs(loose["follower"] - close["follower"]).mean() > 1e-4
    model = ReactionModel.load(leader_noise_model)
    model.spread = 0.5
    assert np.allclose(model.synthesize(sample_data.world(0)[0], {"hugging": 1}, seed=2), loose["follower"], atol=1e-5)
    capsys.readouterr()
    for checkpoint, spread, message in ((tiny_model, "0.5", "has no spread setting"), (leader_noise_model, "1.5", "spread must be")):
        assert main(base + ["--checkpoint", str(checkpoint), "--spread", spread, "--out", str(tmp_path / "no.npz")]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err and not (tmp_path / "no.npz").exists(), err


def test_late_starts_join_the_training_rows_only_when_asked(sample_data, tmp_path):
    """late_start_prob > 0: the trainer's rows include every training pair from a later frame on (never a held-out
    pair's), and batches draw them; 0: the rows and the random stream are as before."""
    plain = DiffusionTrainer(replace(TINY, steps=2), sample_data, "s04", tmp_path / "plain")
    late = DiffusionTrainer(replace(TINY, steps=2, late_start_prob=1.0), sample_data, "s04", tmp_path / "late")
    assert len(plain.padded.lengths) == len(sample_data) and len(plain.late) == 0
    assert len(late.late) == sum(int(sample_data.lengths[i]) - 10 for i in late.train_idx)
    assert len(late.padded.lengths) == len(sample_data) + len(late.late)
    late.fit(progress=False)
    assert (tmp_path / "late" / "final.safetensors").exists()


def test_given_frames_training_scores_only_the_frames_it_samples(sample_data, tmp_path):
    """given_prob: some rows' first frames are given clean and left out of the loss (a network that continues a
    window); it needs the network flag, and the sampler then gives a long take's continued frames clean."""
    with pytest.raises(ValueError, match="given_prob"):
        replace(TINY, given_prob=0.5)
    cfg = replace(TINY, steps=2, given_prob=1.0, late_start_prob=0.5, model=dict(TINY.model) | {"given_frames": True})
    trainer = DiffusionTrainer(cfg, sample_data, "s04", tmp_path / "given")
    parts = trainer.train_step()
    assert np.isfinite(parts["loss"]) and parts["x0"] > 0
    path = trainer.fit(progress=False)
    model = ReactionModel.load(path)
    assert model.config.given_frames
    take = np.concatenate([sample_data.world(i)[0] for i in (0, 40, 80)])
    assert model.synthesize(take, {"kicking": 1.0}).shape == take.shape
