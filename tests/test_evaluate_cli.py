"""`imm evaluate`: the whole report on the bundled checkpoint, and one-line errors for bad input."""

from __future__ import annotations

import json

import pytest

from imm_model.checkpoint import load_checkpoint, save_checkpoint
from imm_model.cli import main
from imm_model.paths import SAMPLE_GAN

CLASSES = ("kicking", "pushing", "shaking_hands", "hugging", "exchanging_objects", "punching")


@pytest.fixture
def quick_classifiers(tmp_path, monkeypatch):
    monkeypatch.setenv("IMM_CACHE_DIR", str(tmp_path / "cache"))
    path = tmp_path / "clf.json"
    path.write_text(json.dumps({"epochs": 2, "hidden": 16, "features": 8}))
    return path


@pytest.mark.slow
def test_evaluate_bundled_checkpoint_against_every_baseline(tmp_path, quick_classifiers, capsys):
    from tests.test_training import TINY

    # the default path: no --men-run, so the label-free baseline is trained through its family and cached (a tiny budget)
    men_cfg = tmp_path / "men.json"
    men_cfg.write_text(json.dumps({"base": "men", "model": TINY.model | {"label_input": False}, "epochs": 1}))
    js, md, fig = tmp_path / "e.json", tmp_path / "e.md", tmp_path / "fig"
    assert main(["evaluate", "--classifier-config", str(quick_classifiers), "--men-config", str(men_cfg), "--quiet",
                 "--json", str(js), "--markdown", str(md), "--figures", str(fig)]) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "cache: trained the men baseline for fold s04" in captured.err
    assert "ratio to the strongest baseline" in out and "| **mean** |" in out
    assert "all folds: AFD, distribution and jitter (95 % interval: bootstrap over sequences" in out  # one run: its bootstrap
    r = json.loads(js.read_text())
    assert r["folds"] == ["s04"] and set(r["groups"]) == {"all", "dev"}
    assert r["followers"] == {"clean_up": True, "average_placement": False}
    for c in CLASSES:
        e = r["classes"][c]
        for key in ("afd", "afd_squared", "fid", "accuracy", "adherence"):
            assert isinstance(e[key], float), (c, key)
        assert set(e["baselines"]) == {"nn1", "knn_dtw", "template", "men"}
        assert all("afd" in b and "fid" in b for b in e["baselines"].values())
        best = min(e["baselines"], key=lambda b: e["baselines"][b]["afd"])
        assert e["strongest_baseline"] == best and e["ratio_strongest"] == pytest.approx(e["afd"] / e["baselines"][best]["afd"])
        assert e["afd"] ** 2 <= e["afd_squared"] + 1e-9  # Jensen: mean of squares >= square of the mean
        assert 0 <= e["contact"] <= 1 and 0 <= e["real_contact"] <= 1
    assert r["classes"]["hugging"]["real_contact"] > r["classes"]["kicking"]["real_contact"]  # hugs touch, kicks rarely
    assert set(r["classifier"]["real_accuracy"]) == {"interaction", "follower", "follower_judge", "upper_judge", "lower_judge"}
    assert 0 <= r["adherence_off_diagonal"] <= 1 and len(r["adherence_matrix"]) == 6
    assert len(r["mix"]) == 15 and {"p_zero", "p_avoid", "change"} <= set(r["avoid"])
    assert {"bone_error_cm", "interpenetration", "foot_skate_mps", "speed_ratio", "jitter_ratio"} <= set(r["plausibility"])
    for key in ("afd", "fid", "kid", "precision", "recall", "jitter_ratio"):  # every headline figure with its interval
        lo, hi = r["model_overall"]["ci"][key]
        value = r["model_overall"][key] if key in r["model_overall"] else r["plausibility"][key]
        assert lo <= hi and (key == "fid" or lo <= value <= hi), (key, lo, value, hi)  # FID's sits above it (docs)
    text = md.read_text()
    assert "### FID per class" in text and "### Mix" in text and "label-free (Men-style)" in text and "### Contact per class" in text
    assert {p.name for p in fig.glob("*.png")} == {"afd.png", "fid.png", "adherence.png", "mix.png", "latent_tsne.png"}


def _one_line_error(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_evaluate_argument_errors(tmp_path, quick_classifiers, capsys):
    assert "--fold all needs per-fold checkpoints" in _one_line_error(["evaluate", "--fold", "all"], capsys)
    assert "not found" in _one_line_error(["evaluate", "--run", "/nonexistent", "--fold", "s01"], capsys)
    assert "'s99'" in _one_line_error(["evaluate", "--fold", "s99"], capsys)
    assert "unknown baseline 'oracle'" in _one_line_error(["evaluate", "--baselines", "nn1,oracle"], capsys)
    assert "at least one of" in _one_line_error(["evaluate", "--baselines", ",,"], capsys)
    assert "run directory not found" in _one_line_error(["evaluate", "--men-run", str(tmp_path / "none")], capsys)
    assert "unknown config 'nobody'" in _one_line_error(["evaluate", "--men-config", "nobody"], capsys)
    missing = ["evaluate", "--classifier-config", str(tmp_path / "none.json")]
    assert "none.json: classifier config not found" in _one_line_error(missing, capsys)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"arch": "lstm"}))
    assert "arch must be one of" in _one_line_error(["evaluate", "--classifier-config", str(bad)], capsys)


def test_checkpoint_that_does_not_match_the_data(tmp_path, quick_classifiers, capsys):
    tensors, meta = load_checkpoint(SAMPLE_GAN)
    meta = {k: v for k, v in meta.items() if k != "format"}
    save_checkpoint(tmp_path / "classes.safetensors", tensors, meta | {"class_names": ["a", "b", "c", "d", "e", "f"]})
    assert "do not match the data's" in _one_line_error(["evaluate", "--checkpoint", str(tmp_path / "classes.safetensors")], capsys)
    skeleton = meta["skeleton"] | {"joint_names": [f"j{i}" for i in range(15)], "name": "other15"}
    save_checkpoint(tmp_path / "skeleton.safetensors", tensors, meta | {"skeleton": skeleton})
    assert "skeleton other15" in _one_line_error(["evaluate", "--checkpoint", str(tmp_path / "skeleton.safetensors")], capsys)


def test_fold_names():
    from imm_model.data.splits import normalize_fold

    assert normalize_fold("4") == normalize_fold("loso-s04") == normalize_fold("s04") == "s04"
    assert normalize_fold("all") == "all" and normalize_fold(None) is None
