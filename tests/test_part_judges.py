"""The bundled body-part judges (sample_data/upper_judge and lower_judge.safetensors): ReadsAs loads and runs them
on the canonical follower (each reads its part of it), they read real held-out followers above chance, a bad file is
a one-line error; and the studio's "reads as" panel reads each part of a mix by body part."""

from __future__ import annotations

import numpy as np
import pytest

from imm_model.checkpoint import load_checkpoint, save_checkpoint
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError
from imm_model.model.body_parts import body_part_view
from imm_model.paths import SAMPLE_JUDGE, SAMPLE_LOWER_JUDGE, SAMPLE_PARTS, SAMPLE_UPPER_JUDGE
from imm_model.reads_as import ReadsAs

PARTS = {"upper": SAMPLE_UPPER_JUDGE, "lower": SAMPLE_LOWER_JUDGE}
pytestmark = pytest.mark.skipif(not all(p.exists() for p in PARTS.values()), reason="bundled part judges missing")


@pytest.mark.parametrize("part", PARTS)
def test_a_bundled_part_judge_loads_and_reads_its_part_of_the_follower(part, sample_data):
    judge = ReadsAs.load(PARTS[part])
    assert judge.part == part and judge.meta["subject"] == "s04" and tuple(judge.class_names) == tuple(sample_data.class_names)
    assert ReadsAs.load(SAMPLE_JUDGE).part is None
    follower = sample_data.canonical(0)[1]
    p = judge.probabilities(follower)
    assert p.shape == (len(judge.class_names),) and p.sum() == pytest.approx(1.0) and np.all(p >= 0)
    view = body_part_view(follower, part).reshape(len(follower), -1)  # the caller passes the canonical follower
    np.testing.assert_allclose(p, judge.classifier.probabilities(view))
    assert "torch" not in judge.classifier.__class__.__module__


@pytest.mark.parametrize("part", PARTS)
def test_a_part_judge_reads_real_held_out_followers_above_chance(part, sample_data):
    judge = ReadsAs.load(PARTS[part])
    test = loso_fold(sample_data.subject_pairs, "s04").test
    hits = [int(np.argmax(judge.probabilities(sample_data.canonical(i)[1])) == sample_data.actions[i]) for i in test]
    accuracy, chance = float(np.mean(hits)), 1 / len(judge.class_names)
    assert accuracy > chance, f"{part} judge: {accuracy:.3f} on {len(hits)} held-out s04 followers (chance {chance:.3f})"
    print(f"{part} judge: {accuracy:.3f} on {len(hits)} held-out s04 followers (chance {chance:.3f})")


def test_a_bad_part_judge_file_is_a_one_line_error(tmp_path):
    import torch

    arrays, meta = load_checkpoint(SAMPLE_UPPER_JUDGE, framework="pt")
    nan = tmp_path / "nan.safetensors"
    save_checkpoint(nan, {k: torch.full_like(v, np.nan) if v.is_floating_point() else v for k, v in arrays.items()}, meta)
    garbage = tmp_path / "garbage.safetensors"
    garbage.write_bytes(b"not a judge")
    interaction = tmp_path / "interaction.safetensors"
    save_checkpoint(interaction, arrays, meta | {"config": meta["config"] | {"inputs": "interaction"}})
    for path, words in ((nan, "not finite"), (garbage, "garbage.safetensors"), (interaction, "needs a follower-only one")):
        with pytest.raises(CheckpointError, match=words) as err:
            ReadsAs.load(path)
        assert "\n" not in str(err.value), str(err.value)


# ---- the studio's panel ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def part_session(sample_data):
    if not SAMPLE_PARTS.exists():
        pytest.skip(f"bundled part model missing: {SAMPLE_PARTS}")
    pytest.importorskip("trame")
    from explorer.session.session import Session, load_model

    parts = {part: ReadsAs.load(p) for part, p in PARTS.items()}
    return Session(sample_data, {"parts": load_model(SAMPLE_PARTS, sample_data)}, index=0,
                   reader=ReadsAs.load(SAMPLE_JUDGE), part_readers=parts)


def test_the_panel_reads_each_part_of_a_part_mix_in_one_line(part_session):
    from explorer.ui.reads_as_panel import PART_NOTE, part_rows, reads_as_rows, unread_note

    ses, C = part_session, len(part_session.class_names)
    shake, push = ses.class_names.index("shaking_hands"), ses.class_names.index("pushing")
    w = np.zeros(2 * C, np.float32)
    w[shake], w[C + push] = 1, -1
    ses.set_label(w)
    readings = ses.readings.reads_as_parts()
    assert set(readings) == {"upper", "lower"} and all(p.sum() == pytest.approx(1.0) for p in readings.values())
    parts = part_rows(readings, ses.label.parts, ses.class_names)
    assert [p["part"] for p in parts] == ["upper body", "lower body"]
    assert parts[0]["asked"]["name"] == "shaking hands" and parts[0]["asked"]["asked"] == "+"
    assert parts[1]["asked"]["name"] == "pushing" and parts[1]["asked"]["asked"] == "-"
    assert all(2 <= len(p["classes"]) <= 3 and p["asked"] in p["classes"] for p in parts)  # the top two, and the asked one
    rows = reads_as_rows(ses.readings.reads_as(), ses.weights, ses.class_names)
    note = unread_note(rows, ses.label.parts_differ, parts)
    up, low = parts[0]["asked"]["p"] * 100, parts[1]["asked"]["p"] * 100
    assert up == pytest.approx(readings["upper"][shake] * 100, abs=0.1)
    upper_words = (f"upper body reads as shaking hands {up:.0f}%"
                   + (", as asked" if up >= 25 else ": not as asked (under 25%)"))
    lower_words = (f"lower body avoids pushing ({low:.0f}%), as asked" if low < 25
                   else f"lower body still reads as pushing {low:.0f}%: asked to avoid it")
    assert note == f"{upper_words} · {lower_words}"
    from explorer.ui.reads_as_panel import part_note

    row = lambda name, p, w: {"name": name, "p": p, "w": w, "asked": "+" if w > 0 else "-", "color": ""}  # noqa: E731
    assert part_note([{"part": "lower body", "asked": row("pushing", 0.0, -1.0), "classes": []}]) == \
        "lower body avoids pushing (0%), as asked"  # a part at -1 that reads 0 % did what was asked
    assert part_note([{"part": "upper body", "asked": row("hugging", 0.12, 1.0), "classes": []}]) == \
        "upper body reads as hugging 12%: not as asked (under 25%)"
    assert part_note([{"part": "upper body", "asked": row("hugging", 0.6, 0.3), "classes": []}]) == \
        "upper body reads as hugging 60% (a nudge of +0.3: not judged)"
    assert unread_note(rows, ses.label.parts_differ) == PART_NOTE  # no part judges: the whole body's caption
    w[C + push], w[C + shake] = 0, 1  # the parts alike again: no part readings
    ses.set_label(w)
    assert not ses.label.parts_differ and ses.readings.reads_as_parts() == {}
