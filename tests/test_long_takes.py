"""Leaders of any length and live reactions in windows (imm_model/families/diffusion/windows.py): the take in windows,
the windows' online reactor's causality, steering and bounds, and the refusals. The bundled diffusion model on real SBU
leaders."""

from __future__ import annotations

import numpy as np
import pytest

from imm_model.cleanup import OnlineCleanup
from imm_model.errors import DataFormatError, LabelError
from imm_model.families.diffusion.sampler import Guidance, ddim, keeping
from imm_model.families.diffusion.windows import BLEND, LIVE_STEPS, LOOKAHEAD, RESAMPLE, STRIDE, TAKE_LOOKAHEAD
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DEFAULT, SAMPLE_DIFFUSION, SAMPLE_GAN, SAMPLE_RETRIEVAL


@pytest.fixture(scope="module")
def model():
    """The bundled diffusion model reacting live in windows: its live reactor set aside (test_live_reactor.py)."""
    m = ReactionModel.load(SAMPLE_DIFFUSION)
    m.live = None
    yield m
    m.raw = False


@pytest.fixture(scope="module")
def take(sample_data):
    """Three real leaders played one after another (their world frames joined end to end): longer than the window."""
    return np.concatenate([sample_data.world(i)[0] for i in (0, 40, 80)])


def react_online(model, leader, label, seed=0, change_at=None, new_label=None):
    reactor = model.online(label, seed=seed)
    out = []
    for t, frame in enumerate(leader):
        if t == change_at:
            reactor.label = new_label
        f = reactor.push(frame)
        if f is not None:
            out.append(f)
    return reactor, np.concatenate([np.stack(out), reactor.flush()])


def test_known_frames_are_held_at_every_step():
    values = np.full((1, 5, 3), 7.0, np.float32)
    where = np.array([[True, True, False, False, False]])
    seen = []

    def predict(x, step):
        seen.append(x.copy())
        return np.zeros_like(x)

    out = keeping(predict, (values, where, False))(np.zeros((1, 5, 3), np.float32), 3)
    assert (out[0, :2] == 7).all() and (out[0, 2:] == 0).all()
    assert (seen[-1] == 0).all()  # a network not trained on given frames reads them noised, as the sampler made them
    keeping(predict, (values, where, True))(np.zeros((1, 5, 3), np.float32), 3)
    assert (seen[-1][0, :2] == 7).all() and (seen[-1][0, 2:] == 0).all()  # one trained so reads them clean
    assert keeping(predict, None) is predict


def test_resampling_takes_each_step_again_and_keeps_the_given_frames():
    """RePaint's resampling in the sampling loop: every step but the last is taken `times` more times, from its
    result noised back; the given frames stay as given, its noise follows the rows' keys, and 0 times is the plain
    loop bit for bit."""
    rng = np.random.default_rng(0)
    values = rng.standard_normal((2, 6, 3)).astype(np.float32)
    where = np.zeros((2, 6), bool)
    where[:, :2] = True
    mask = np.ones((2, 6), bool)
    calls = []

    def predict(x, step):  # a toy network whose prediction depends on its input
        calls.append(step)
        return np.tanh(0.5 * x + 0.1 * step / 100).astype(np.float32)

    held = keeping(predict, (values, where, False))
    guidance = Guidance(sample_steps=4)
    noise = rng.standard_normal((2, 6, 3)).astype(np.float32)
    plain = ddim(held, noise, mask, guidance, 100)
    n_plain = len(calls)
    np.testing.assert_array_equal(ddim(held, noise, mask, guidance, 100, resample=(0, [1, 2])), plain)
    calls.clear()
    again = ddim(held, noise, mask, guidance, 100, resample=(3, [(0, 4), (0, 8)]))
    assert len(calls) == (n_plain - 1) * 4 + 1  # the last step's prediction is the answer: not taken again
    np.testing.assert_array_equal(again[:, :2], values[:, :2])
    assert np.abs(again[:, 2:] - plain[:, 2:]).max() > 1e-3
    np.testing.assert_array_equal(ddim(held, noise, mask, guidance, 100, resample=(3, [(0, 4), (0, 8)])), again)
    other = ddim(held, noise, mask, guidance, 100, resample=(3, [(0, 4), (0, 9)]))
    np.testing.assert_array_equal(other[0], again[0])  # each row's noise from its own key
    assert np.abs(other[1, 2:] - again[1, 2:]).max() > 1e-4


def test_a_long_take_s_windows_resample_and_a_clip_does_not(model, take, sample_data):
    """A long take's windows take each step RESAMPLE more times (windows.py); a clip is sampled once, whatever the
    setting, and a draft (a student drawing while a slider moves) takes each step once."""
    assert model.resample == RESAMPLE > 0
    clip = sample_data.world(7)[0]
    label = {"hugging": 1.0}
    shipped_take, shipped_clip = model.synthesize(take, label, seed=1), model.synthesize(clip, label, seed=1)
    model.resample = 0
    try:
        once_take, once_clip = model.synthesize(take, label, seed=1), model.synthesize(clip, label, seed=1)
    finally:
        model.resample = RESAMPLE
    np.testing.assert_array_equal(once_clip, shipped_clip)
    assert np.abs(once_take - shipped_take).max() > 0.01
    np.testing.assert_array_equal(model.synthesize(take, label, seed=1), shipped_take)  # deterministic per seed
    student = ReactionModel.load(SAMPLE_DEFAULT)
    assert student.takes is not None and student.takes.resample == RESAMPLE and student.draft.resample == 0


def test_a_live_push_takes_live_steps_and_a_clip_the_model_s_own(model, take, monkeypatch):
    """A push samples its window in LIVE_STEPS network calls (windows.py `live`), fewer than the model's own, which a
    clip still takes; the model itself keeps its steps."""
    steps = model.guidance.sample_steps
    assert LIVE_STEPS < steps
    calls = []
    network = type(model)._denoiser

    def counted(self, *args, **kwargs):
        denoise = network(self, *args, **kwargs)
        return lambda x_t, step, *rest: calls.append(step) or denoise(x_t, step, *rest)

    monkeypatch.setattr(type(model), "_denoiser", counted)
    reactor = model.online({"kicking": 1.0})
    for frame in take[:LOOKAHEAD]:
        assert reactor.push(frame) is None
    assert not calls
    assert reactor.push(take[LOOKAHEAD]) is not None
    assert len(calls) == LIVE_STEPS
    calls.clear()
    model.synthesize(take[:40], {"kicking": 1.0})
    assert len(calls) == steps == model.guidance.sample_steps


def test_a_long_take_is_made_a_few_frames_at_a_time(model, take, sample_data):
    """Longer than the trained clips: each window makes the next frames from the leader up to its lookahead, so frames
    made before a window read a change of the leader stay as they were; a clip no longer than the training clips is
    sampled whole, as before."""
    assert len(take) > model.window
    model.raw = True
    try:
        whole = model.synthesize(take, {"pushing": 1.0}, seed=2)
        changed = take.copy()
        t = 60
        changed[t:] += np.array([0.5, 0.0, 0.3])  # the leader steps away from frame 60 on
        moved = model.synthesize(changed, {"pushing": 1.0}, seed=2)
        clip = sample_data.world(7)[0]
        assert len(clip) <= model.window
        np.testing.assert_array_equal(model.synthesize(clip, {"pushing": 1.0}, seed=2),
                                      model.synthesize_leaders([clip], model.label_vector({"pushing": 1.0}), [2])[0].astype(np.float32))
    finally:
        model.raw = False
    assert whole.shape == take.shape and np.isfinite(whole).all()
    before = t - TAKE_LOOKAHEAD - STRIDE - BLEND  # a later window crossfades the last BLEND frames made
    np.testing.assert_array_equal(moved[:before], whole[:before])
    assert np.abs(moved[t:] - whole[t:]).max() > 0.05
    steps = np.linalg.norm(np.diff(whole, axis=0), axis=-1).mean(1)  # mean joint motion per frame
    still = np.linalg.norm(np.diff(take, axis=0), axis=-1).mean(1) < 0.1  # not where one leader ends and the next begins
    assert steps[still].max() < 0.25  # no window starts anew somewhere else (a jump of metres)


def test_a_long_take_continues_given_frames_and_keeps_them(model, take):
    """`take_windows(..., given=)`: the follower's first frames kept exactly as given (none crossfaded), the rest made
    from there."""
    from imm_model.families.diffusion.windows import take_windows

    label = model._label_input(model.label_vector({"pushing": 1.0})[None])[0]
    given = np.full((40, *take.shape[1:]), 0.5)  # anywhere: nothing the sampler would have made
    made = take_windows(model, take, label, 3, given=given)
    np.testing.assert_array_equal(made[:40], given.astype(np.float32))
    assert made.shape == take.shape and np.isfinite(made).all() and np.abs(made[40:] - 0.5).max() > 0.1


def test_any_length_is_taken_up_to_the_bound(model, sample_data):
    leader = np.concatenate([sample_data.world(3)[0]] * 20)  # 20 copies: beyond the old 10x the longest clip
    assert len(leader) > 10 * model.window
    model.resample = 0  # the length is what is tested here, not the windows' resampling (a third of the time)
    try:
        assert model.synthesize(leader, {"kicking": 1.0}).shape == leader.shape
    finally:
        model.resample = RESAMPLE
    too_long = np.zeros((model.max_length + 1, 15, 3))
    with pytest.raises(DataFormatError, match="at most"):
        model.check_leader(too_long)


def test_online_frames_never_read_beyond_the_lookahead(model, take):
    leader = take[:40]
    _, base = react_online(model, leader, {"hugging": 1.0})
    assert base.shape == leader.shape and np.isfinite(base).all()
    changed = leader.copy()
    t = 20
    changed[t + 1 + model.online({"hugging": 1.0}).lookahead:] += np.array([0.5, 0.0, 0.3])  # the leader steps away later
    _, moved = react_online(model, changed, {"hugging": 1.0})
    np.testing.assert_array_equal(moved[: t + 1], base[: t + 1])
    assert not np.allclose(moved[t + 1:], base[t + 1:])


def test_online_push_protocol_and_bounded_memory(model, take):
    reactor = model.online({"kicking": 1.0})
    assert 0 < reactor.lookahead <= 4
    outs = [reactor.push(f) for f in take]
    assert all(o is None for o in outs[: reactor.lookahead])
    assert all(o is not None and o.shape == (15, 3) and o.dtype == np.float32 for o in outs[reactor.lookahead:])
    assert len(reactor._leader) <= reactor.window and len(reactor._follower) <= reactor.window
    assert reactor.flush().shape == (reactor.lookahead, 15, 3)
    assert reactor.flush().shape == (0, 15, 3)


def test_a_label_changed_live_changes_the_next_frames_only(model, sample_data):
    leader = sample_data.world(int(np.argmax([len(sample_data.world(i)[0]) for i in range(len(sample_data))])))[0]
    _, kept = react_online(model, leader, {"pushing": 1.0})
    _, steered = react_online(model, leader, {"pushing": 1.0}, change_at=25, new_label={"pushing": -1.0, "hugging": 1.0})
    behind = 25 - model.online({"pushing": 1.0}).lookahead  # frames returned before the change
    np.testing.assert_array_equal(steered[:behind], kept[:behind])
    assert np.abs(steered[behind:] - kept[behind:]).max() > 0.05
    step = lambda f: np.linalg.norm(np.diff(f, axis=0), axis=-1).max(1)  # noqa: E731 - the fastest joint's step
    recorded = np.concatenate([step(sample_data.world(i)[1]) for i in range(0, len(sample_data), 5)])
    # it turns, it does not jump to another pose: its fastest joint no faster than recorded followers' but 1 % of frames
    assert step(steered)[behind - 1:].max() <= np.percentile(recorded, 99)


def test_online_seeds_are_variations(model, take):
    _, a = react_online(model, take[:30], {"pushing": 1.0}, seed=0)
    _, b = react_online(model, take[:30], {"pushing": 1.0}, seed=0)
    _, c = react_online(model, take[:30], {"pushing": 1.0}, seed=5)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.01


def test_online_refusals_are_one_line(model):
    reactor = model.online({"kicking": 1.0})
    for bad, match in ((np.zeros((14, 3)), "shape"), (np.full((15, 3), np.nan), "NaN"), ("x", "numeric"),
                       (np.full((15, 3), 1e9), "from the origin")):
        with pytest.raises(DataFormatError, match=match) as err:
            reactor.push(bad)
        assert "\n" not in str(err.value)
    assert reactor.frames_in == 0  # a refused frame is not taken
    with pytest.raises(LabelError, match="unknown class"):
        reactor.label = {"dancing": 1.0}
    with pytest.raises(LabelError):
        model.online({"kicking": float("nan")})
    for path in (SAMPLE_GAN, SAMPLE_RETRIEVAL):
        other = ReactionModel.load(path)
        assert not other.settings.online
        with pytest.raises(LabelError, match="cannot react online"):
            other.online({"kicking": 1.0})


def test_online_cleanup_holds_a_planted_foot(model, sample_data):
    """A foot on the floor sliding in the network's frames stays where it touched down, frame by frame."""
    pose = sample_data.world(0)[1][0].astype(np.float64)  # a real follower's first pose
    names, up = model.skeleton.joint_names, model.skeleton.vertical_axis
    foot = min((names.index("left_foot"), names.index("right_foot")), key=lambda j: pose[j, up])  # the one on the floor
    frames = np.repeat(pose[None], 6, 0)
    frames[:, foot, 0] += np.linspace(0, 0.1, 6)  # skating 2 cm a frame along the floor
    clean = OnlineCleanup(model.skeleton, model.bone_lengths)
    out = np.concatenate([clean(frames[t:t + 1]) for t in range(6)])
    assert np.abs(out[:, foot, 0] - out[0, foot, 0]).max() < 1e-3
    lifted = frames.copy()
    lifted[3:, foot, up] += 0.3  # lifted from frame 3: it leaves its spot without a jump
    out = np.concatenate([OnlineCleanup(model.skeleton, model.bone_lengths)(lifted[t:t + 1]) for t in range(6)])
    assert out[5, foot, 0] > out[0, foot, 0] + 0.05


def test_online_cleanup_drags_a_foot_sliding_far_along_rather_than_leave_it_behind(model, sample_data):
    """A follower sliding 1 m over the floor (as a live follower made to walk on may): a planted foot is held only
    until the network's foot is PIN_REACH_M from it, then dragged along, so that it never lags the body and snaps back
    when lifted."""
    pose = sample_data.world(0)[1][0].astype(np.float64)
    names, up = model.skeleton.joint_names, model.skeleton.vertical_axis
    foot = min((names.index("left_foot"), names.index("right_foot")), key=lambda j: pose[j, up])
    frames = np.repeat(pose[None], 21, 0)
    frames[:, :, 0] += np.linspace(0, 1.0, 21)[:, None]  # the whole body slides 5 cm a frame
    clean = OnlineCleanup(model.skeleton, model.bone_lengths)
    out = np.concatenate([clean(frames[t:t + 1]) for t in range(21)])
    horizontal = [a for a in range(3) if a != up]
    lag = np.linalg.norm(out[:, foot, horizontal] - frames[:, foot, horizontal], axis=-1)
    assert lag.max() <= 0.35, lag.round(3)  # held where it touched down, it lags 0.58 m (the leg cannot reach it)
    assert lag[:3].max() > 0.04  # held at first: a planted foot still does not skate


def test_the_command_line_reacts_to_a_long_take(sample_data, tmp_path, capsys):
    """`imm generate --leader` with a BVH take longer than any training clip: a follower for every frame."""
    from imm_model.cli import main
    from imm_model.data.bvh import read_bvh, write_bvh

    take = np.concatenate([sample_data.world(i)[0] for i in (0, 40, 80, 120)])
    leader = tmp_path / "take.bvh"
    write_bvh(leader, take, sample_data.skeleton, 15.0)
    out = tmp_path / "reaction.bvh"
    assert main(["generate", "--leader", str(leader), "--label", "hugging=1", "--out", str(out)]) in (0, None)
    follower = read_bvh(out)
    assert len(follower) == len(take) > 2 * 46 and np.isfinite(follower).all()
    assert f"follower {len(take)} frames" in capsys.readouterr().out


def test_the_studio_session_live_keeps_what_was_made_and_refuses_a_model_that_cannot(sample_data):
    """Live mode in the session (explorer/session/live.py): frames made as the leader plays; a new mix keeps them and
    steers the rest; a model without an online reactor is refused in one line, on and while live, nothing changed."""
    from explorer.session.session import Session, load_model

    ses = Session(sample_data, {"diffusion": load_model(SAMPLE_DIFFUSION, sample_data),
                                "gan": load_model(SAMPLE_GAN, sample_data)}, index=5)
    ses.set_live(True)
    for frame in range(10):
        ses.live.reach(frame)
    made, past = ses.live.made, ses.synth[: ses.live.made].copy()
    assert 10 <= made < ses.num_frames
    w = np.zeros(len(ses.class_names), np.float32)
    w[3] = 1.0
    ses.set_label(w)
    np.testing.assert_array_equal(ses.synth[:made], past)
    assert [f for f, _ in ses.live.steered] == [0, made]
    with pytest.raises(LabelError, match="cannot react live") as err:
        ses.set_model("gan")
    assert "\n" not in str(err.value) and ses.model_name == "diffusion" and ses.live.on
    ses.set_live(False)
    ses.set_model("gan")
    with pytest.raises(LabelError, match="cannot react live"):
        ses.set_live(True)
    assert not ses.live.on


def test_votes_average_every_window_that_made_a_frame():
    """A live frame is the weighted mean of every window's sample of it: equal weights at growth 1, the later window
    alone as the growth grows without bound."""
    from imm_model.families.diffusion import windows

    votes = windows.Votes(1)
    votes.add(np.zeros((3, 1, 3))).add(np.ones((3, 1, 3)))
    np.testing.assert_allclose(votes.take(1)[:, 0, 0], [0.5])
    votes.add(np.full((3, 1, 3), 4.0))
    np.testing.assert_allclose(votes.take(3)[:, 0, 0], [5 / 3, 5 / 3, 4.0])  # the third frame: one window's sample
    assert votes.take(2).shape == (0, 1, 3)


def test_live_frames_averaged_over_windows_move_less_than_one_window_each(model, take, monkeypatch):
    """One window's sample per frame made every live frame a seam; averaged over the windows that sampled it, the
    follower's largest step from one frame to the next (a seam's) is smaller."""
    from imm_model.families.diffusion import windows

    step = lambda f: np.linalg.norm(np.diff(f, axis=0), axis=-1).max(1)  # noqa: E731 - the fastest joint's step
    _, averaged = react_online(model, take[:40], {"pushing": 1.0})
    monkeypatch.setattr(windows, "ENSEMBLE_GROWTH", 1e12)  # the window that returns a frame alone
    _, alone = react_online(model, take[:40], {"pushing": 1.0})
    assert step(averaged).max() < 0.8 * step(alone).max()
