"""The retrieval family: the 1-NN baseline as a model, through every front end."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from imm_model.cli import main
from imm_model.data.dataset import InteractionDataset
from imm_model.data.splits import loso_fold
from imm_model.errors import CheckpointError
from imm_model.evaluation.baselines import nearest_neighbour_follower
from imm_model.families import load_model
from imm_model.families.retrieval.model import asked_classes
from imm_model.paths import SAMPLE_DATA, SAMPLE_RETRIEVAL


@pytest.fixture(scope="module")
def data():
    return InteractionDataset.load(SAMPLE_DATA)


def test_imm_generate_with_the_retrieval_checkpoint_writes_the_1nn_baselines_reaction(data, tmp_path):
    fold = loso_fold(data.subject_pairs, "s04")
    for i in fold.test[::12]:
        sid, own = data.sequence_ids[i], data.action_name(i)
        out = tmp_path / f"{i}.npz"
        assert main(["generate", "--sequence", sid, "--checkpoint", str(SAMPLE_RETRIEVAL), "--label", f"{own}=1",
                     "--out", str(out)]) == 0
        with np.load(out) as written:
            np.testing.assert_allclose(written["follower_canonical"], nearest_neighbour_follower(data, fold.train, i), atol=1e-5)


def test_the_label_picks_the_class_retrieved_from(data):
    model = load_model(SAMPLE_RETRIEVAL)
    assert list(asked_classes(np.array([0, 1, 0.5, 0, 0, 0.]))) == [1]  # the class asked for most
    assert list(asked_classes(np.array([0, -1, 0, 0, 0, 0.]))) == [0, 2, 3, 4, 5]  # avoided: any other
    assert list(asked_classes(-np.ones(6))) == [0, 1, 2, 3, 4, 5]
    leader = data.world(0)[0]
    hug, avoid_hug = model.synthesize(leader, {"hugging": 1.0}), model.synthesize(leader, {"hugging": -1.0})
    assert not np.allclose(hug, avoid_hug)
    np.testing.assert_array_equal(model.synthesize(leader, {"hugging": 1.0}, scale=2.0), hug)  # the scale picks nothing


def test_the_retrieved_reaction_is_real_motion_never_cleaned(data):
    model = load_model(SAMPLE_RETRIEVAL)
    i = int(loso_fold(data.subject_pairs, "s04").test[0])
    label = np.eye(6, dtype=np.float32)[data.actions[i]]
    model.raw = False
    cleaned = model.synthesize_canonical(data.canonical(i)[0], label)
    model.raw = True
    np.testing.assert_array_equal(cleaned, model.synthesize_canonical(data.canonical(i)[0], label))


def test_imm_train_writes_a_retrieval_checkpoint_per_fold(tmp_path, capsys):
    assert main(["train", "--config", "retrieval", "--fold", "s02", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    model = load_model(tmp_path / "run" / "fold-s02" / "final.safetensors")
    assert model.family == "retrieval" and model.held_out_subject == "s02"
    assert main(["train", "--config", "retrieval", "--steps", "5", "--out", str(tmp_path / "other")]) == 2
    assert "--steps does not apply to 'retrieval' (1-NN retrieval)" in capsys.readouterr().err


def test_a_retrieval_checkpoint_whose_data_is_gone_or_changed_is_refused_in_one_line(tmp_path, data):
    shutil.copy(SAMPLE_RETRIEVAL, tmp_path / "r.safetensors")
    meta = json.loads(SAMPLE_RETRIEVAL.with_suffix(".json").read_text())
    (tmp_path / "r.json").write_text(json.dumps(meta | {"retrieval": meta["retrieval"] | {"data_file": "elsewhere.npz",
                                                                                          "data_path": "elsewhere.npz"}}))
    with pytest.raises(CheckpointError, match="its training data elsewhere.npz .* is neither beside it nor among the bundled"):
        load_model(tmp_path / "r.safetensors")
    (tmp_path / "r.json").write_text(json.dumps(meta | {"retrieval": meta["retrieval"] | {"data_hash": "0" * 16}}))
    with pytest.raises(CheckpointError, match="content hash 0000000000000000"):
        load_model(tmp_path / "r.safetensors")


@pytest.mark.parametrize("written", ["../../../../etc/passwd", "/etc/passwd"])
def test_a_retrieval_sidecar_never_makes_imm_open_a_path_written_in_it(tmp_path, monkeypatch, written):
    """The data is found beside the checkpoint, among the bundled data, or where the user names it; a path in the
    sidecar (whoever wrote the file chose it) is never opened."""
    from imm_model.data.dataset import InteractionDataset

    opened = []
    real_load = InteractionDataset.load
    monkeypatch.setattr(InteractionDataset, "load", classmethod(lambda cls, p, *a, **k: opened.append(str(p)) or real_load(p, *a, **k)))
    shutil.copy(SAMPLE_RETRIEVAL, tmp_path / "r.safetensors")
    meta = json.loads(SAMPLE_RETRIEVAL.with_suffix(".json").read_text())
    (tmp_path / "r.json").write_text(json.dumps(meta | {"retrieval": meta["retrieval"] | {"data_path": written,
                                                                                          "data_file": written}}))
    with pytest.raises(CheckpointError, match="its training data passwd .* is neither beside it nor among the bundled"):
        load_model(tmp_path / "r.safetensors")
    assert not any("etc" in p for p in opened), opened


def test_a_retrieval_model_reads_the_bundle_the_user_names(tmp_path, data):
    """Trained on a bundle kept elsewhere: found with --data (load's `data`), refused in one line without it."""
    from imm_model.paths import SAMPLE_DATA

    elsewhere = tmp_path / "bundles" / "mine.npz"
    elsewhere.parent.mkdir()
    shutil.copy(SAMPLE_DATA, elsewhere)
    assert main(["train", "--config", "retrieval", "--fold", "s02", "--data", str(elsewhere), "--out", str(tmp_path / "run"),
                 "--quiet"]) == 0
    final = tmp_path / "run" / "fold-s02" / "final.safetensors"
    assert "data_path" not in json.loads(final.with_suffix(".json").read_text())["retrieval"]
    with pytest.raises(CheckpointError, match=r"mine.npz .* \(name it with --data\)"):
        load_model(final)
    assert load_model(final, data=elsewhere).held_out_subject == "s02"
