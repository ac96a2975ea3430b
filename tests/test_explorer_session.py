"""Studio logic without a browser: session (label mixing, synthesis, review numbers, export)."""

from __future__ import annotations

import io
from types import SimpleNamespace

import numpy as np
import pytest

from imm_model.data.labels import Label
from imm_model.errors import CheckpointError
from imm_model.paths import SAMPLE_GAN

CLASSES = ("kicking", "pushing", "shaking_hands", "hugging", "exchanging_objects", "punching")  # SBU's, as bundled

pytest.importorskip("trame")


@pytest.fixture(scope="module")
def model(sample_data):
    if not SAMPLE_GAN.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_GAN}")
    from explorer.session.session import load_model

    return load_model(SAMPLE_GAN, sample_data)


@pytest.fixture()
def session(sample_data, model):
    from explorer.session.session import Session

    return Session(sample_data, {"gan": model}, index=0)


def test_label_words():
    from explorer.session.words import label_words

    names = ("kicking", "pushing", "shaking_hands", "hugging")
    assert label_words([0, 0, 1, 1], names) == "shaking hands +1, hugging +1"
    assert label_words([0.5, -1, 0, 0], names, scale=2) == "kicking +0.5, pushing -1  × 2"
    assert label_words([0, 0, 0, 0], names).startswith("neutral")


def test_select_matches_own_class(session, sample_data):
    i = int(np.flatnonzero(sample_data.actions == 3)[0])
    session.select(i)
    assert session.weights.tolist() == [1.0 if c == 3 else 0.0 for c in range(len(sample_data.class_names))]
    assert session.label_text() == "hugging +1"
    assert session.synth.shape == session.ground_truth.shape == sample_data.canonical(i)[1].shape


def test_mixing_changes_synthesis(session):
    session.match()
    matched = session.synth.copy()
    w = session.weights.copy()
    w[(session.own_class + 1) % len(w)] = 1.0
    session.set_label(w)
    assert not np.allclose(session.synth, matched)
    session.reset()
    assert session.label_text().startswith("neutral")
    session.set_label(session.weights, scale=0.0)
    assert np.isfinite(session.synth).all()


def test_review_numbers(session, sample_data):
    d = session.readings.distances_m()
    assert d.shape == (session.num_frames,) and (d >= 0).all()
    pairs = zip(session.synth, session.ground_truth, strict=True)
    manual = [np.mean([np.linalg.norm(a - b) for a, b in zip(s, g, strict=True)]) for s, g in pairs]
    np.testing.assert_allclose(d, manual, rtol=1e-5)  # the mean distance between corresponding joints
    assert np.isfinite(session.readings.afd()) and session.readings.afd() > 0


def test_filters(session, sample_data):
    from explorer.session.session import SequenceRow

    held = SequenceRow.matching(session.data, held_out=True)
    assert held and all(sample_data.held_out[i] for i in held)
    kick = SequenceRow.matching(session.data, class_name="kicking")
    assert kick and all(sample_data.action_name(i) == "kicking" for i in kick)
    pair = sample_data.subject_pairs[5]
    assert all(sample_data.subject_pairs[i] == pair for i in SequenceRow.matching(session.data, subject_pair=pair))
    assert "[held out]" in SequenceRow.all_of(session.data)[held[0]].title


def test_export_npz_roundtrip(session, sample_data, tmp_path):
    """The studio writes the project's one .npz layout: world and canonical motions, skeleton, label; and
    `imm generate --leader` reads it back."""
    from imm_model.cli import main

    raw = session.files.npz()
    with np.load(io.BytesIO(raw)) as z:
        np.testing.assert_allclose(z["follower_canonical"], session.synth, atol=1e-5)
        np.testing.assert_allclose(z["leader"], sample_data.world(session.index)[0], atol=1e-5)
        np.testing.assert_allclose(z["ground_truth"], sample_data.world(session.index)[1], atol=1e-5)
        assert list(z["class_names"]) == list(session.class_names) and list(z["parents"]) == list(sample_data.skeleton.parents)
        assert str(z["format"]) == "imm-interaction-1" and float(z["fps"]) == 15.0
    assert session.files.name("npz").endswith(".npz") and "/" not in session.files.name("npz")
    (tmp_path / "s.npz").write_bytes(raw)
    assert main(["generate", "--leader", str(tmp_path / "s.npz"), "--label", "hugging=1", "--out", str(tmp_path / "o.npz")]) == 0


def test_export_bvh_reimports(session, tmp_path):
    from imm_model.data.bvh import read_bvh

    (tmp_path / "f.bvh").write_bytes(session.files.bvh("follower"))
    np.testing.assert_allclose(read_bvh(tmp_path / "f.bvh"), session.world(session.synth), atol=1e-3)


def test_mismatched_model_is_one_line(sample_data):
    from imm_model.inference import check_compatible

    wrong_classes = SimpleNamespace(class_names=("a", "b"), skeleton=sample_data.skeleton)
    with pytest.raises(CheckpointError, match="classes a, b do not match"):
        check_compatible(wrong_classes, sample_data, "ckpt")
    sk = sample_data.skeleton
    wrong_skel = SimpleNamespace(
        class_names=sample_data.class_names,
        skeleton=SimpleNamespace(name="other", joint_names=sk.joint_names[:-1], parents=sk.parents[:-1]),
    )
    with pytest.raises(CheckpointError, match="skeleton other") as err:
        check_compatible(wrong_skel, sample_data, "ckpt")
    assert "\n" not in str(err.value)
    other_frame = SimpleNamespace(class_names=sample_data.class_names, skeleton=sk, canonical_mode="per_frame")
    with pytest.raises(CheckpointError, match="canonical frame"):
        check_compatible(other_frame, sample_data, "ckpt")


def test_reads_as_follows_the_label(sample_data, model):
    """The 'reads as' panel's numbers: the bundled follower-only classifier on the synthesized follower."""
    from explorer.session.session import Session
    from explorer.ui.reads_as_panel import reads_as_rows
    from imm_model.paths import SAMPLE_JUDGE
    from imm_model.reads_as import ReadsAs

    reader = ReadsAs.load(SAMPLE_JUDGE)
    ses = Session(sample_data, {"gan": model}, index=0, reader=reader)
    p = ses.readings.reads_as()
    assert p.shape == (6,) and p.sum() == pytest.approx(1.0) and np.all(p >= 0)
    before = p.copy()
    other = (ses.own_class + 3) % 6
    ses.set_label(np.eye(6)[other])
    assert not np.allclose(ses.readings.reads_as(), before)  # a new label, a new reading
    rows = reads_as_rows(ses.readings.reads_as(), ses.weights, ses.class_names)
    assert [r["asked"] for r in rows].count("+") == 1 and rows[other]["asked"] == "+"
    assert Session(sample_data, {"gan": model}, index=0).readings.reads_as() is None  # no classifier, no panel


def test_the_panel_names_asked_classes_that_do_not_read():
    from explorer.ui.reads_as_panel import reads_as_rows, unread_note

    names = ("kicking", "pushing", "hugging")
    mixed = reads_as_rows(np.array([0.05, 0.15, 0.80]), [1, 0, 1], names)
    assert unread_note(mixed) == "Does not read as asked: kicking 5% (under 25%)"  # one wording, one class or several
    alone = reads_as_rows(np.array([0.20, 0.60, 0.20]), [1, 0, 0], names)
    assert unread_note(alone) == "Does not read as asked: kicking 20% (under 25%)"
    assert unread_note(reads_as_rows(np.array([0.30, 0.05, 0.65]), [1, -1, 1], names)) == ""  # both read; avoided is not asked
    assert unread_note([]) == ""
    nudged = reads_as_rows(np.array([0.02, 0.08, 0.90]), [0.05, 0, 1], names)  # a 0.05 nudge is not an ask
    assert nudged[0]["asked"] == "+" and unread_note(nudged) == ""


def test_reads_as_refuses_other_classes_and_files(sample_data, model, tmp_path):
    from explorer.session.session import Session
    from imm_model.reads_as import ReadsAs

    with pytest.raises(CheckpointError, match="classes"):
        Session(sample_data, {"gan": model}, reader=SimpleNamespace(class_names=("a", "b")))
    bad = tmp_path / "x.safetensors"
    bad.write_bytes(b"not a file")
    with pytest.raises(CheckpointError):
        ReadsAs.load(bad)
    with pytest.raises(CheckpointError, match="not a reaction classifier"):
        ReadsAs.load(SAMPLE_GAN)


def test_reads_as_centres_a_start_centred_conv_classifier(sample_data, tmp_path):
    """A start-centred conv classifier file runs on torch (which centres it), not on the numpy runtime (which would not):
    a follower shifted sideways reads the same."""
    from imm_model.checkpoint import save_checkpoint
    from imm_model.model.classifier import MotionClassifier
    from imm_model.model.classifier_config import ClassifierConfig
    from imm_model.reads_as import ReadsAs

    cfg = ClassifierConfig(inputs="follower", arch="conv", start_centred=True)
    path = tmp_path / "centred.safetensors"
    save_checkpoint(path, MotionClassifier(cfg, 45, 6).state_dict(),
                    {"kind": "classifier", "config": cfg.to_dict(), "class_names": list(sample_data.class_names)})
    reader = ReadsAs.load(path)
    follower = sample_data.canonical(0)[1]
    np.testing.assert_allclose(reader.probabilities(follower + np.array([0.5, 0.0, -0.2], np.float32)),
                               reader.probabilities(follower), atol=1e-5)


def test_playback_speed_and_picture_size_from_the_page_are_clamped():
    from explorer.ui.playback import MIN_PLAYBACK_SCALE, PLAYBACK_SCALE, playback_scale, playback_speed

    assert playback_speed(1.5) == 1.5 and playback_speed(None) == 1.0 and playback_speed("x") == 1.0
    assert playback_speed(1e-300) == 0.25 and playback_speed(-2) == 0.25 and playback_speed(1e9) == 2.0
    assert playback_speed(float("nan")) == 1.0
    assert playback_scale(0.75) == 0.75 and playback_scale(7) == 1.0 and playback_scale(0) == MIN_PLAYBACK_SCALE
    assert playback_scale(None) == playback_scale(float("nan")) == playback_scale("x") == PLAYBACK_SCALE


def test_uploaded_leader_has_no_ground_truth_and_bad_files_change_nothing(session, sample_data, tmp_path):
    from imm_model.data.bvh import write_bvh
    from imm_model.errors import IMMError

    write_bvh(tmp_path / "l.bvh", sample_data.world(9)[0])
    before = session.synth.copy()
    for name, content, message in (("x.obj", b"v 0 0 0", "unsupported file type"), ("x.bvh", b"", "not a BVH file"),
                                   ("x.npz", b"garbage", "unreadable"), ("x.bvh", b"x" * 20_000_001, "up to 20 MB")):
        with pytest.raises(IMMError, match=message):
            session.load_upload(name, content)
        assert session.upload is None and np.array_equal(session.synth, before)  # nothing changed
    session.load_upload("l.bvh", (tmp_path / "l.bvh").read_bytes())
    assert session.upload.name == "l.bvh" and session.ground_truth is None and session.own_class is None
    assert session.synth.shape == session.leader.shape == sample_data.canonical(9)[0].shape
    np.testing.assert_allclose(session.leader, sample_data.canonical(9)[0], atol=2e-3)  # same canonical frame
    assert session.readings.afd() is None and len(session.readings.distances_m()) == 0
    with np.load(io.BytesIO(session.files.npz())) as z:
        assert "ground_truth" not in z.files and "sequence_id" not in z.files
    assert session.files.name("bvh").startswith("l_")
    from explorer.ui.exports import about_text

    assert about_text(session).endswith(" · l.bvh")  # exported pictures name the uploaded file
    session.select(0)
    assert session.upload is None and session.ground_truth is not None


def test_pin_a_mix_and_compare(session):
    """A/B: the pinned mix keeps its follower while the sliders move; it follows a new leader; clear drops it."""
    assert session.pinned.follower is None and len(session.pinned.distances_m()) == 0
    session.pinned.pin()
    pinned, words = session.pinned.follower.copy(), session.pinned.text()
    assert np.allclose(session.pinned.distances_m(), 0)
    w = np.zeros(len(session.class_names), np.float32)
    w[3] = 1.0
    session.set_label(w, 1.0)
    assert np.array_equal(session.pinned.follower, pinned) and session.pinned.text() == words
    assert session.pinned.distances_m().mean() > 0.01 and len(session.pinned.distances_m()) == session.num_frames
    session.select(5)  # the pinned mix is re-synthesized for the new leader
    assert session.pinned.follower.shape == session.leader.shape and session.pinned.text() == words
    session.pinned.clear()
    assert session.pinned.follower is None and session.pinned.text() == ""


def test_contact_marks_the_interpenetrating_frames_and_bones(session):
    from explorer.rendering.charts import contact_text, distance_chart, penetration_ranges
    from imm_model.evaluation.plausibility import PENETRATION_M, closest_distances

    assert penetration_ranges(np.array([0.1, 0.01, 0.02, 0.2, 0.04])) == [(1, 2), (4, 4)]
    assert penetration_ranges(np.array([0.3, 0.2])) == [] and "no interpenetration" in contact_text(np.array([0.3, 0.2]))
    session.select(5)  # a hug the bundled model pushes into the leader (found by scanning the sample)
    cleaned = session.synth.copy()
    session.set_cleanup(False)  # the network's own follower (the clean-up only makes its bones rigid, feet planted)
    assert not np.allclose(session.synth, cleaned)
    closest, leader_bones, follower_bones = session.readings.contact()
    np.testing.assert_allclose(closest, closest_distances(session.leader, session.synth, session.data.skeleton))
    inside = closest < PENETRATION_M
    assert inside.any() and np.array_equal(inside, leader_bones.any(1)) and np.array_equal(inside, follower_bones.any(1))
    assert f"in {int(inside.sum())} of {len(closest)} frames" in contact_text(closest)
    chart = distance_chart(session.readings.distances_m(), 15.0, closest=closest)
    assert chart.count('class="penetration"') == len(penetration_ranges(closest)) and chart.count("<polyline") == 2
    session.set_cleanup(True)
    np.testing.assert_allclose(session.synth, cleaned)


def test_chart_ticks_and_markup():
    from explorer.rendering.charts import distance_chart, nice_ticks

    assert nice_ticks(0.83) == [0, 0.25, 0.5, 0.75] and nice_ticks(0.7) == [0, 0.2, 0.4, 0.6] and nice_ticks(95, 6) == [0, 20, 40, 60, 80]
    assert nice_ticks(0.0) == [0.0]

    assert distance_chart(np.array([0.1, 0.2]), 15.0).count("imm-tick-x") == 2  # frames 0 and 1, no 0.5
    assert "<polyline" not in distance_chart(np.zeros(0), 15.0)  # an upload without ground truth or contact yet


# ---- two models: the switch, seeds and variations ---------------------------------------------------------------


@pytest.fixture(scope="module")
def diffusion(sample_data):
    from explorer.session.session import load_model
    from imm_model.paths import SAMPLE_DIFFUSION

    if not SAMPLE_DIFFUSION.exists():
        pytest.skip(f"bundled diffusion model missing: {SAMPLE_DIFFUSION}")
    return load_model(SAMPLE_DIFFUSION, sample_data)


@pytest.fixture()
def two_models(sample_data, model, diffusion):
    from explorer.session.session import Session

    model.raw = diffusion.raw = False
    return Session(sample_data, {"gan": model, "diffusion": diffusion}, index=3)


def test_switching_models_keeps_the_sequence_mix_and_pin(two_models):
    ses = two_models
    assert ses.model_name == "gan" and not ses.seeded and set(ses.models) == {"gan", "diffusion"}
    ses.set_label(np.eye(6)[2] * 0.5 + np.eye(6)[4] * -0.5, scale=1.5)
    ses.pinned.pin()
    gan, mix, index = ses.synth.copy(), ses.weights.copy(), ses.index
    ses.set_model("diffusion")
    assert ses.model_name == "diffusion" and ses.seeded and ses.model_title() == "the diffusion model"
    assert ses.index == index and np.array_equal(ses.weights, mix) and ses.scale == 1.5
    assert ses.synth.shape == gan.shape and not np.allclose(ses.synth, gan)  # another model, another reaction
    np.testing.assert_array_equal(ses.pinned.follower, gan)  # the pin keeps its model: A/B compares the two
    assert "the paper's GAN" in ses.pinned.text() and ses.pinned.distances_m().mean() > 0.01
    assert ses.mix_latent().shape == ses.map_model.latent_canonical_batch([ses.leader], ses.vector[None]).shape[1:]
    ses.select(7)  # a new leader: the pinned mix follows it with its own model
    np.testing.assert_allclose(ses.pinned.follower, ses.models["gan"].synthesize_canonical(
        ses.leader, ses.models["gan"].label_vector(list(mix), 1.5)), atol=1e-6)
    ses.set_model("gan")
    assert ses.model_name == "gan" and "GAN" not in ses.pinned.text()
    with pytest.raises(ValueError, match="no model 'x'"):
        ses.set_model("x")
    assert ses.model_name == "gan"


def test_exported_pictures_name_the_model_its_seed_and_the_leader(two_models):
    from explorer.ui.exports import about_text

    ses = two_models
    assert about_text(ses) == f"the paper's GAN · {ses.data.sequence_ids[3]}"
    ses.set_model("diffusion")
    ses.set_seed(7)
    assert about_text(ses) == f"the diffusion model, seed 7 · {ses.data.sequence_ids[3]}"
    ses.set_cleanup(False)
    assert "no clean-up" in about_text(ses)
    ses.set_cleanup(True)


def test_a_seed_picks_a_variation_and_a_moved_slider_moves_it_smoothly(two_models):
    from imm_model.errors import LabelError

    ses = two_models
    ses.set_model("diffusion")
    first = ses.synth.copy()
    ses.set_seed(0)
    np.testing.assert_allclose(ses.synth, first, atol=1e-6)  # the same seed, the same reaction
    ses.set_seed(5)
    assert ses.seed == 5 and np.abs(ses.synth - first).mean() > 0.01
    fifth = ses.synth.copy()
    w = ses.weights.copy()
    nudges = []
    for step in (0.01, 0.05):  # a small slider move: a small change, growing with the move, not another sample
        w[(ses.own_class + 1) % 6] = step
        ses.set_label(w)
        nudges.append(np.abs(ses.synth - fifth).mean())
    ses.match()
    ses.set_seed(6)
    assert 0 < nudges[0] < nudges[1] and nudges[0] < 0.3 * np.abs(ses.synth - fifth).mean(), nudges
    seen = {ses.seed}
    for _ in range(3):
        before = ses.synth.copy()
        ses.new_variation()
        assert ses.seed not in seen and np.abs(ses.synth - before).mean() > 0.005
        seen.add(ses.seed)
    for bad in (-1, 2**31, 1.5, "3", True):
        with pytest.raises(LabelError, match="seed"):
            ses.set_seed(bad)
    assert ses.seed in seen  # a refused seed changes nothing


def test_variations_are_the_seeds_side_by_side(two_models):
    ses = two_models
    ses.set_model("diffusion")
    ses.set_seed(40)
    followers = ses.side_by_side.drawn(3)
    assert len(followers) == 3 and followers[0] is ses.synth
    for k, f in enumerate(followers):  # each as drawn alone with its seed
        np.testing.assert_allclose(f, ses.model.synthesize_canonical(ses.leader, ses.vector, seed=40 + k), atol=1e-4)
    assert np.abs(followers[1] - followers[2]).mean() > 0.01
    ses.side_by_side.set_count(4)
    assert len(ses.side_by_side.variations) == 4 and ses.side_by_side.seeds() == [40, 41, 42, 43]
    ses.set_label(np.eye(6)[1])  # a new mix redraws them all
    np.testing.assert_allclose(ses.side_by_side.variations[3],
                               ses.model.synthesize_canonical(ses.leader, ses.vector, seed=43), atol=1e-4)
    with np.load(io.BytesIO(ses.files.npz())) as z:  # the exported file says which variation it holds
        assert int(z["seed"]) == 40
    ses.set_model("gan")  # a deterministic model: one reaction, whatever the seed
    assert len(ses.side_by_side.variations) == 1 and all(f is ses.synth for f in ses.side_by_side.drawn(4))
    with np.load(io.BytesIO(ses.files.npz())) as z:
        assert "seed" not in z.files
    for bad in (0, 5, 2.0):
        with pytest.raises(ValueError, match="1..4"):
            ses.side_by_side.set_count(bad)


def test_the_clean_up_switch_holds_for_both_models(two_models):
    ses = two_models
    ses.set_cleanup(False)
    ses.set_model("diffusion")
    assert ses.model.raw and not ses.cleaned_up
    ses.set_cleanup(True)
    assert not ses.models["gan"].raw and not ses.models["diffusion"].raw


def test_a_link_carries_the_model_and_the_seed():
    from explorer.ui.url_state import MAX_SEED, parse_view, view_query

    query = view_query({"seq": "s01s02/03/001", "label": Label.of({"kicking": 1.0}, CLASSES), "model": "diffusion", "seed": 12})
    assert query.endswith("&model=diffusion&seed=12")
    view, problems = parse_view(query, ("kicking",), {"s01s02/03/001"}, ("default",), ("gan", "diffusion"))
    assert (view["model"], view["seed"], problems) == ("diffusion", 12, [])
    bad = f"?model=flow&seed={MAX_SEED + 1}&frame=3"
    view, problems = parse_view(bad, ("kicking",), set(), ("default",), ("gan", "diffusion"))
    assert view == {"frame": 3} and problems == ["model 'flow' is not one of gan, diffusion",
                                                 f"seed '{MAX_SEED + 1}' is outside 0..{MAX_SEED}"]
    assert parse_view("?seed=-1", (), set(), (), ("gan",))[1] == ["seed '-1' is not a whole number"]


def test_a_sliders_variations_can_wait_for_its_first_picture(two_models):
    ses = two_models
    ses.set_model("diffusion")
    ses.side_by_side.set_count(3)
    before = [f.copy() for f in ses.side_by_side.variations]
    ses.set_label(np.eye(6)[4], variations=False)
    assert ses.side_by_side.due and ses.side_by_side.variations[0] is ses.synth
    np.testing.assert_array_equal(ses.side_by_side.variations[2], before[2])  # the earlier mix's, until drawn
    ses.side_by_side.draw()
    assert not ses.side_by_side.due
    np.testing.assert_allclose(ses.side_by_side.variations[2],
                               ses.model.synthesize_canonical(ses.leader, ses.vector, seed=ses.seed + 2), atol=1e-4)
    ses.side_by_side.set_count(1)


@pytest.fixture(scope="module")
def retrieval(sample_data):
    from explorer.session.session import load_model
    from imm_model.paths import SAMPLE_RETRIEVAL

    if not SAMPLE_RETRIEVAL.exists():
        pytest.skip(f"bundled retrieval model missing: {SAMPLE_RETRIEVAL}")
    return load_model(SAMPLE_RETRIEVAL, sample_data)


def test_compared_models_followers_are_each_models_own_synthesis(sample_data, model, diffusion, retrieval):
    """Other models beside the current one: each one's follower is what it draws as the current model, and they follow
    the sequence, the mix, the seed and the clean-up; a slider's wait with the variations."""
    from explorer.session.session import Session

    model.raw = diffusion.raw = retrieval.raw = False
    ses = Session(sample_data, {"gan": model, "diffusion": diffusion, "retrieval": retrieval}, index=3)
    ses.side_by_side.set_compared(["retrieval", "diffusion", "gan"])  # the current one among them is drawn once, as `synth`
    assert ses.side_by_side.compared == ("gan", "diffusion", "retrieval") and ses.side_by_side.compared_names == ("diffusion", "retrieval")
    ses.set_seed(7)
    ses.set_label(np.eye(6)[2] * 0.5 + np.eye(6)[4], scale=1.2)
    ses.select(5, match_label=False)
    ses.set_cleanup(False)
    drawn = {name: f.copy() for name, f in ses.side_by_side.compared_followers.items()}
    assert set(drawn) == {"diffusion", "retrieval"} and ses.side_by_side.caption("diffusion") == "the diffusion model\nseed 7"
    assert ses.side_by_side.caption("retrieval") == "1-NN retrieval"
    gan = ses.synth.copy()
    for name in ("diffusion", "retrieval"):
        ses.set_model(name)
        np.testing.assert_allclose(drawn[name], ses.synth, atol=1e-5)
        assert name not in ses.side_by_side.compared_names and "gan" in ses.side_by_side.compared_followers
        np.testing.assert_allclose(ses.side_by_side.compared_followers["gan"], gan, atol=1e-5)
    ses.set_model("gan")
    assert np.abs(drawn["diffusion"] - drawn["retrieval"]).mean() > 0.01
    ses.set_label(np.eye(6)[1], variations=False)  # a slider: the others follow with the variations
    assert ses.side_by_side.due
    np.testing.assert_array_equal(ses.side_by_side.compared_followers["diffusion"], drawn["diffusion"])
    ses.side_by_side.draw()
    np.testing.assert_allclose(ses.side_by_side.compared_followers["diffusion"],
                               diffusion.synthesize_canonical(ses.leader, ses.vector, seed=7), atol=1e-5)
    with pytest.raises(ValueError, match="compare: no model 'flow'; this studio has gan, diffusion, retrieval"):
        ses.side_by_side.set_compared(["diffusion", "flow"])
    assert ses.side_by_side.compared == ("gan", "diffusion", "retrieval")
    ses.side_by_side.set_compared([])
    assert ses.side_by_side.compared_followers == {}
    ses.set_cleanup(True)


def test_a_link_carries_the_compared_models():
    from explorer.ui.url_state import parse_view, view_query

    query = view_query({"seq": "s01s02/03/001", "label": Label.of({"kicking": 1.0}, CLASSES), "compare": "diffusion,retrieval"})
    assert query.endswith("&compare=diffusion,retrieval")
    models = ("gan", "diffusion", "retrieval")
    assert parse_view(query, ("kicking",), {"s01s02/03/001"}, (), models)[0]["compare"] == ["diffusion", "retrieval"]
    assert parse_view("?compare=flow", (), set(), (), models)[1] == ["compare: model 'flow' is not one of gan, diffusion, retrieval"]
    assert parse_view("?compare=a,b,c,d", (), set(), (), "abcde")[1] == ["compare: at most 3 models, not 4"]
    assert parse_view("?compare=gan,gan", (), set(), (), models)[0]["compare"] == ["gan"]


@pytest.fixture(scope="module")
def spreading(sample_data, tmp_path_factory):
    """A tiny diffusion model trained a few steps with noised leaders (real data; its reactions are not results)."""
    from dataclasses import replace

    import torch

    from explorer.session.session import load_model
    from imm_model.families.diffusion.recipes import IMM_DIFFUSION
    from imm_model.families.diffusion.trainer import DiffusionTrainer

    torch.set_num_threads(1)
    cfg = replace(IMM_DIFFUSION, name="tiny-spread", model=dict(width=16, layers=1, heads=2, ff_mult=1, dropout=0.0,
                                                                leader_noise=True),
                  guidance=dict(label_scale=2.5, sample_steps=4, leader_noise=0.2), leader_noise_prob=0.5, steps=12,
                  batch_size=8, warmup_steps=2)
    path = DiffusionTrainer(cfg, sample_data, "s04", tmp_path_factory.mktemp("spread") / "fold-s04").fit(progress=False)
    return load_model(path, sample_data)


def test_the_spread_moves_the_reaction_and_travels_with_the_pin_link_and_export(sample_data, model, spreading):
    """The spread (a model trained with noised leaders) redraws the follower with the same seed; a bad value or a model
    without the setting is refused in one line and changes nothing; the pin keeps its own spread; links and the
    exported file carry it."""
    from explorer.session.session import Session
    from explorer.ui.url_state import parse_view, view_query
    from imm_model.errors import LabelError

    ses = Session(sample_data, {"gan": model, "diffusion": spreading}, index=3)
    assert ses.spread is None
    with pytest.raises(LabelError, match="has no spread setting"):
        ses.set_spread(0.5)
    with pytest.raises(LabelError, match="has no spread setting"):
        model.spread = 0.5  # the model itself refuses it: nothing is stored beside the GAN
    assert ses.spread is None
    ses.set_model("diffusion")
    assert ses.spread == pytest.approx(0.2)  # the model's own default
    ses.set_label(np.eye(6)[1])
    loose = ses.synth.copy()
    ses.set_spread(0.0)
    close = ses.synth.copy()
    assert np.abs(close - loose).mean() > 1e-4
    ses.set_spread(0.2)
    assert np.array_equal(ses.synth, loose)  # the same seed and spread draw the same reaction again
    for bad in (1.5, float("nan"), "wide"):
        with pytest.raises(LabelError, match="spread must be a number in 0..1"):
            ses.set_spread(bad)
        assert ses.spread == pytest.approx(0.2) and np.array_equal(ses.synth, loose)
    ses.pinned.pin()
    ses.set_spread(0.0)
    assert ses.pinned.text().endswith("spread 0.2") and np.array_equal(ses.pinned.follower, loose)
    ses.select(5)  # the pinned follower is redrawn for the new leader with its own spread, not the current one
    pinned_at_5 = ses.pinned.follower.copy()
    ses.set_label(np.eye(6)[1])  # a new sequence opens on its own class: back to the pinned mix
    ses.set_spread(0.2)
    assert np.array_equal(ses.synth, pinned_at_5) and ses.spread == pytest.approx(0.2)
    with np.load(io.BytesIO(ses.files.npz())) as f:
        assert float(f["spread"]) == pytest.approx(0.2)
    kicking = Label.of({"kicking": 1.0}, CLASSES)
    query = view_query({"seq": "s01s02/03/001", "label": kicking, "model": "diffusion", "seed": 4, "spread": 0.35})
    assert query.endswith("&seed=4&spread=0.35")
    view, problems = parse_view(query.replace("0.35", "2"), ("kicking",), {"s01s02/03/001"}, ("default",), ("gan", "diffusion"))
    assert "spread" not in view and problems == ["spread '2' is outside 0..1"]
