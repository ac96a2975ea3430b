"""Mixing by body part in the studio: the session's part mix (its label vector, words, link, export) beside a model
without part labels, over a network trained with a label per body part for 60 steps at a small width (its motion is
meaningless: only the plumbing is tested); and the Label mix drawer's part control in a browser, on the studio as it
opens by default: the bundled diffusion model, whose sampler joins the parts (Guidance.part_join), beside the GAN and
1-NN retrieval (no part labels)."""

from __future__ import annotations

import io

import numpy as np
import pytest

from imm_model.errors import LabelError
from imm_model.paths import SAMPLE_DIFFUSION, SAMPLE_GAN

pytest.importorskip("trame")

C = 6  # SBU's classes: kicking, pushing, shaking_hands, hugging, exchanging_objects, punching
SHAKE, PUSH = 2, 1


@pytest.fixture(scope="module")
def part_checkpoint(tmp_path_factory, sample_data):
    import torch

    from imm_model.families.diffusion.recipes import IMM_DIFFUSION_PARTS, DiffusionTrainConfig
    from imm_model.families.diffusion.trainer import train

    # 60 steps at width 64 (~7 s) and the label guidance at its strongest, at every step: a label moves this barely
    # trained follower by ~0.2 m, which a picture shows (at 20 steps and width 32 it moves it by less than a millimetre)
    cfg = DiffusionTrainConfig.from_dict(IMM_DIFFUSION_PARTS.to_dict() | {
        "steps": 60, "batch_size": 8, "checkpoint_every": 60,
        "model": IMM_DIFFUSION_PARTS.model | {"width": 64, "layers": 2, "heads": 2},
        "guidance": IMM_DIFFUSION_PARTS.guidance | {"label_scale": 20.0, "guided_below": 1.0}})
    out = tmp_path_factory.mktemp("parts")
    torch.set_num_threads(1)
    train(cfg, sample_data, "s04", out, progress=False)
    return out / "final.safetensors"


@pytest.fixture()
def session(sample_data, part_checkpoint):
    """A part model first (it opens), the bundled GAN (no part labels) one switch away."""
    if not SAMPLE_GAN.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_GAN}")
    from explorer.session.session import Session, load_model

    models = {"diffusion": load_model(part_checkpoint, sample_data), "gan": load_model(SAMPLE_GAN, sample_data)}
    return Session(sample_data, models, index=0)


def part_mix(upper: dict[int, float], lower: dict[int, float]) -> np.ndarray:
    w = np.zeros(2 * C, np.float32)
    for k, v in upper.items():
        w[k] = v
    for k, v in lower.items():
        w[C + k] = v
    return w


def test_a_part_mix_is_the_models_part_label_and_reads_back_as_its_keys(session):
    ses = session
    assert ses.part_labels and not ses.label.parts_differ
    whole = ses.synth.copy()
    ses.set_label(part_mix({SHAKE: 1}, {PUSH: -1}), scale=0.5)
    assert ses.label.parts_differ and ses.label.keys() == {"upper:shaking_hands": 1.0, "lower:pushing": -1.0}
    np.testing.assert_array_equal(ses.vector, ses.model.label_vector({"upper:shaking_hands": 1, "lower:pushing": -1}, 0.5))
    assert ses.vector.shape == (2 * C,) and not np.allclose(ses.synth, whole)
    assert ses.label_text() == "trunk and arms: shaking hands +1 · legs: pushing -1  × 0.5"  # in words, not as keys
    np.testing.assert_array_equal(ses.weights, [0, -0.5, 0.5, 0, 0, 0])  # one weight per class: the parts' mean
    assert "upper_shaking_hands+1" in ses.files.name("npz").replace(":", "_")
    # a class alone with a part overriding it; both parts alike again is the whole-body label, (C,)
    ses.set_label(part_mix({0: 1, SHAKE: 1}, {0: 1}), scale=1.0)
    assert ses.label.keys() == {"kicking": 1.0, "upper:shaking_hands": 1.0}
    assert ses.label_text() == "kicking +1 · trunk and arms: shaking hands +1"
    ses.set_label(part_mix({0: 1}, {0: 1}))
    assert not ses.label.parts_differ and ses.vector.shape == (C,) and ses.label_text() == "kicking +1"


def test_the_exported_interaction_and_strip_carry_the_part_keys(session):
    from explorer.ui.exports import mix_text

    session.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    with np.load(io.BytesIO(session.files.npz())) as f:
        assert str(f["label_text"]) == "upper:shaking_hands=1,lower:pushing=-1" and f["label"].shape == (2 * C,)
    assert mix_text(session.label) == "upper:shaking_hands=1,lower:pushing=-1 · scale 1.00"


def test_a_model_without_part_labels_is_refused_while_a_part_mix_is_set(session):
    ses = session
    ses.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    synth, vector = ses.synth.copy(), ses.vector.copy()
    with pytest.raises(LabelError, match="^the paper's GAN takes no label per body part: link each class's parts"):
        ses.set_model("gan")
    assert ses.model_name == "diffusion" and np.array_equal(ses.synth, synth) and np.array_equal(ses.vector, vector)
    with pytest.raises(LabelError, match="^compare: the paper's GAN takes no label per body part"):
        ses.side_by_side.set_compared(["gan"])
    assert ses.side_by_side.compared == ()
    ses.pinned.pin()  # the pin keeps the part mix, in its keys
    assert ses.pinned.text() == "trunk and arms: shaking hands +1 · legs: pushing -1"
    assert ses.mix_latent().shape == ses.map_model.latent_canonical_batch([ses.leader], ses.vector[None]).shape[1:]
    ses.set_label(part_mix({SHAKE: 1}, {SHAKE: 1}))  # linked again: the switch goes through, the mix stays
    ses.set_model("gan")
    assert ses.model_name == "gan" and not ses.part_labels and ses.label_text() == "shaking hands +1"
    with pytest.raises(LabelError, match="takes no label per body part"):  # a part mix on the GAN: nothing changes
        ses.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    assert not ses.label.parts_differ and ses.model_name == "gan"
    ses.set_model("diffusion")
    ses.side_by_side.set_compared(["gan"])  # the GAN beside it: no part mix while it is drawn too
    assert not ses.part_labels
    with pytest.raises(LabelError, match="^compare: the paper's GAN"):
        ses.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    assert not ses.label.parts_differ


def test_a_link_writes_and_restores_a_part_mix_and_names_a_bad_part_key(session):
    from explorer.ui.url_state import parse_view, view_query

    session.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    query = view_query({"label": session.label})
    assert "mix=upper:shaking_hands:1,lower:pushing:-1" in query
    names = session.class_names
    view, problems = parse_view(query, names, set(), ())
    assert view["mix"].keys() == {"upper:shaking_hands": 1.0, "lower:pushing": -1.0} and not problems
    assert parse_view("?mix=kicking:1,upper:hugging:0.5", names, set(), ())[0]["mix"].keys() == {"kicking": 1.0, "upper:hugging": 0.5}
    for bad, words in (("middle:kicking:1", "mix: unknown class 'middle:kicking'; classes: kicking, pushing"),
                       ("upper:dancing:1", "mix: unknown class 'upper:dancing'"),
                       ("lower:pushing:2", "mix weight of lower:pushing 2 is outside -1..1"),
                       ("kicking:1,kicking:-1", "mix: the label gives kicking twice"),
                       ("kicking", "mix: 'kicking' is not a label item: write class:value")):
        view, problems = parse_view(f"?mix={bad}&frame=3", names, set(), ())
        assert len(problems) == 1 and problems[0].startswith(words) and view == {"frame": 3}, problems


def test_a_part_link_opened_on_a_model_without_part_labels_says_so_in_one_line(session):
    from types import SimpleNamespace

    from explorer.ui.url_state import apply_view

    moved = []
    state = _State()
    holder = SimpleNamespace(session=session, state=state, scene=None, load_sequence=lambda i: None,
                             set_label=lambda w, scale=1.0: moved.append((list(w), scale)), set_camera=lambda p: None)
    apply_view(holder, "?mix=upper:shaking_hands:1,lower:pushing:-1")
    assert moved and len(moved[-1][0]) == 2 * C and not state.error  # the part model reads it: the sliders take it
    session.set_model("gan")
    moved.clear()
    apply_view(holder, "?mix=upper:shaking_hands:1&scale=0.5")
    assert state.error == ("link: mix: the paper's GAN takes no label per body part ('upper:shaking_hands'); "
                           "give the class alone, for the whole body")
    assert moved == [(list(session.label.mix), 0.5)]  # the rest of the link still applies


class _State(dict):
    """trame's state as apply_view uses it: attributes, and a `with` block."""

    def __getattr__(self, key):
        return self.get(key)

    def __setattr__(self, key, value):
        self[key] = value

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


# ---- a part mix is never drawn as another label ------------------------------------------------------------------------
def test_a_part_link_with_a_compared_model_without_part_labels_is_named_and_the_mix_left_out(session):
    from types import SimpleNamespace

    from explorer.ui.url_state import apply_view

    moved, state = [], _State()
    holder = SimpleNamespace(session=session, state=state, scene=None, load_sequence=lambda i: None,
                             set_label=lambda w, scale=1.0: moved.append((list(w), scale)), set_camera=lambda p: None)
    session.side_by_side.set_compared(["gan"])
    apply_view(holder, "?mix=upper:shaking_hands:1,lower:pushing:-1")
    assert state.error == ("link: mix: compare: the paper's GAN takes no label per body part: link each class's parts "
                           "(or reset the mix) first")
    assert all(len(w) == C for w, _ in moved)  # never the part mix's upper half as a whole-body label


def test_the_sliders_keep_a_part_mix_whatever_the_models_and_a_nan_is_refused_in_one_line(session):
    """The sliders' mix is what they show: a part mix stays one (the session refuses it where a model cannot draw it),
    and a NaN from a hostile client is named as such, the mix drawn before kept."""
    from types import SimpleNamespace

    from explorer.ui.label_mixer import LabelMixer

    state = _State(scale=1.0, part_labels=False)
    for i in range(C):
        state[f"w_{i}"], state[f"lower_{i}"], state[f"apart_{i}"] = 0.0, 0.0, False
    state[f"w_{SHAKE}"], state[f"lower_{SHAKE}"], state[f"apart_{SHAKE}"] = 1.0, -1.0, True
    mixer = SimpleNamespace(page=SimpleNamespace(state=state, session=session))
    label = LabelMixer.slider_mix(mixer)
    assert label.keys() == {"upper:shaking_hands": 1.0, "lower:shaking_hands": -1.0}
    session.set_model("gan")
    before = session.synth.copy()
    with pytest.raises(LabelError, match="the paper's GAN takes no label per body part"):
        session.set_label(label)
    state[f"w_{SHAKE}"] = float("nan")
    with pytest.raises(LabelError, match="label values must be finite"):
        session.set_label(LabelMixer.slider_mix(mixer))
    state[f"w_{SHAKE}"] = "a lot"
    with pytest.raises(LabelError, match="value for 'shaking_hands' is not a number: 'a lot'"):
        LabelMixer.slider_mix(mixer)
    np.testing.assert_array_equal(session.synth, before)


def test_swapping_in_a_pinned_part_mix_under_a_model_without_part_labels_is_refused_and_the_pin_kept(session):
    from types import SimpleNamespace

    from explorer.ui.compare import Compare

    session.set_label(part_mix({SHAKE: 1}, {PUSH: -1}))
    session.pinned.pin()
    session.set_label(np.eye(C)[0])
    session.set_model("gan")
    moved = []
    page = SimpleNamespace(session=session, state=_State(), ctrl=SimpleNamespace(view_update=lambda **k: None),
                           guarded=lambda f: f)
    compare = Compare(page, SimpleNamespace(set_pinned=lambda p: None), set_label=lambda *a: moved.append(a),
                      update_review=lambda: None)
    pinned = session.pinned.label
    with pytest.raises(LabelError, match="the paper's GAN takes no label per body part"):
        compare.swap()
    assert session.pinned.label is pinned and pinned.parts_differ and not moved  # nothing lost, nothing drawn
    assert session.label.keys() == {"kicking": 1.0}


def test_a_link_with_a_huge_value_is_named_in_a_short_line(session):
    from explorer.ui.url_state import parse_view

    _, problems = parse_view("?model=" + "x" * 1990, session.class_names, set(), (), tuple(session.models))
    assert len(problems) == 1 and len(problems[0]) < 200 and problems[0].startswith("model 'xxxx"), problems


# ---- the drawer in a browser ------------------------------------------------------------------------------------------
@pytest.mark.browser
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_drawer_sets_a_class_apart_for_one_part_and_the_link_and_picture_follow(browser, tmp_path):
    """At 1366x768, the studio as it opens by default (the bundled diffusion model, its sampler joining the parts): a
    class's parts set apart in the Label mix drawer, its lower body's slider moved: the label text, the link, the
    picture and the part judges' readings follow; the GAN and retrieval (no part labels) are marked, and a switch to
    the GAN is refused in one line, while the parts differ."""
    from tests import studio_probe as probe

    if not SAMPLE_DIFFUSION.exists():
        pytest.skip(f"bundled checkpoint missing: {SAMPLE_DIFFUSION}")
    with probe.StudioProcess(cache_dir=tmp_path) as studio:  # no --model: the bundled models, the default first
        page = probe.open_studio(browser, studio.url, 1366, 768, timeout_ms=180000)
        try:
            probe.watch_view_images(page)
            probe.wait_state(page, "s.get('part_labels') === true && s.get('mix_count') > 0 && s.get('url_query') !== ''")
            assert [m["value"] for m in probe.state(page, "model_items")] == ["diffusion", "gan", "retrieval"]
            assert probe.state(page, "model_name") == "diffusion" and probe.state(page, "model_title") == "the diffusion model"
            page.click("#reset-label")
            probe.wait_state(page, "s.get('label_text').startsWith('neutral')")
            probe.press_slider(page, ".slider-shaking_hands", "End")  # shaking hands +1, the whole body
            probe.wait_state(page, "s.get('label_text') === 'shaking hands +1'")
            probe.wait_for_view_at_rest(page)
            before = probe.view_pixels(page)
            assert page.locator(".lower-slider-shaking_hands").count() == 0
            page.click("#parts-2")  # apart: the lower body's slider appears where the class's is
            probe.wait_state(page, "s.get('apart_2') === true && s.get('lower_2') === 1")
            probe.press_slider(page, ".lower-slider-shaking_hands", "Home")  # the legs avoid it
            probe.wait_state(page, "s.get('label_text') === 'trunk and arms: shaking hands +1 · legs: shaking hands -1'")
            probe.wait_state(page, "s.get('url_query').includes('mix=upper:shaking_hands:1,lower:shaking_hands:-1')")
            probe.wait_state(page, "s.get('parts_apart') === true")  # a model that would refuse the part mix is marked
            for name in ("gan", "retrieval"):
                other = page.locator(f"#model-{name}")
                assert other.is_disabled() and "takes no label per body part" in (other.get_attribute("title") or ""), name
            assert not page.locator("#model-diffusion").is_disabled()
            page.wait_for_function("() => location.search.includes('mix=upper:shaking_hands:1,lower:shaking_hands:-1')")
            # the bundled part judges read each part: two compact readings, the asked class of each marked, one note
            probe.wait_state(page, "s.get('reads_as_parts').length === 2")
            parts = probe.state(page, "reads_as_parts")
            assert [p["part"] for p in parts] == ["upper body", "lower body"]
            assert parts[0]["asked"]["asked"] == "+" and parts[1]["asked"]["asked"] == "-"
            assert page.locator("#reads-as-parts .reads-as-part").count() == 2
            note = page.locator("#reads-as-note").inner_text()
            assert note.startswith("upper body reads as shaking hands ") and "lower body" in note and "shaking hands" in note, note
            assert ("as asked" in note) or ("not as asked" in note) or ("asked to avoid it" in note), note
            page.locator("#reads-as").screenshot(path=str(probe.ARTIFACTS / "studio-parts-reads-as.png"))
            probe.wait_for_view_at_rest(page)
            changed = int((np.abs(probe.view_pixels(page).astype(int) - before.astype(int)).sum(-1) > 60).sum())
            assert changed > 200, changed  # the follower moved
            page.locator("#label-text").scroll_into_view_if_needed()
            probe.shot(page, "studio-parts-drawer")
            page.locator(".v-navigation-drawer").screenshot(path=str(probe.ARTIFACTS / "studio-parts-drawer-only.png"))
            probe.set_state(page, "model_name", "gan")  # a switch the page would not send (its button is off): refused
            probe.wait_state(page, "s.get('error').includes('takes no label per body part')")
            probe.wait_state(page, "s.get('model_name') === 'diffusion' && s.get('computing') === false")
            assert probe.state(page, "apart_2") is True
            page.click("#parts-2")  # linked again: both parts take the class's slider, and the switch goes through
            probe.wait_state(page, "s.get('label_text') === 'shaking hands +1' && s.get('reads_as_parts').length === 0")
            assert page.locator("#reads-as-parts").count() == 0
            page.click("#model-gan")
            probe.wait_state(page, "s.get('model_name') === 'gan' && s.get('part_labels') === false")
            assert page.locator("#parts-2").count() == 0
        finally:
            page.close()
