"""`imm evaluate`: per-class AFD of model and nearest neighbour, ratio, JSON/Markdown outputs."""

from __future__ import annotations

import json

from imm_model.cli import main


def test_evaluate_bundled_checkpoint(tmp_path, capsys):
    js, md = tmp_path / "e.json", tmp_path / "e.md"
    assert main(["evaluate", "--json", str(js), "--markdown", str(md)]) == 0
    out = capsys.readouterr().out
    assert "LOSO folds: s04" in out and "mean ratio" in out
    result = json.loads(js.read_text())
    assert set(result["afd_model"]) == set(result["afd_nn"]) == set(result["ratio"])
    assert len(result["ratio"]) == 6
    for c, r in result["ratio"].items():
        assert abs(r - result["afd_model"][c] / result["afd_nn"][c]) < 1e-9
    assert "| **mean** |" in md.read_text()


def test_evaluate_argument_errors(capsys):
    assert main(["evaluate", "--fold", "all"]) == 2
    assert "--fold all needs per-fold checkpoints" in capsys.readouterr().err
    assert main(["evaluate", "--run", "/nonexistent", "--fold", "s01"]) == 2
    assert "not found" in capsys.readouterr().err


def test_fold_names():
    from imm_model.evaluation.commands import normalize_fold

    assert normalize_fold("4") == normalize_fold("loso-s04") == normalize_fold("s04") == "s04"
    assert normalize_fold("all") == "all" and normalize_fold(None) is None
