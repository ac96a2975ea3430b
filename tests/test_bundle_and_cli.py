"""The bundled sample file and the `imm data` commands."""

from __future__ import annotations

import hashlib
import subprocess
import sys

import numpy as np
import pytest

from imm_model.cli import main
from imm_model.data.dataset import InteractionDataset
from imm_model.paths import SAMPLE_DATA


def test_bundle_contents(sample_data):
    assert len(sample_data) == 197 and int(sample_data.lengths.sum()) == 5058
    assert sample_data.class_names == ("kicking", "pushing", "shaking_hands", "hugging", "exchanging_objects", "punching")
    assert np.bincount(sample_data.actions).tolist() == [40, 41, 18, 21, 39, 38]
    assert len(set(sample_data.subject_pairs)) == 21
    held = sample_data.info["held_out_subject"]
    assert sample_data.held_out.sum() == sum(held in p for p in sample_data.subject_pairs) > 0
    assert "Yun" in sample_data.info["citation"] and "research" in sample_data.info["terms"]
    assert SAMPLE_DATA.stat().st_size < 5e6


@pytest.mark.shared
def test_build_sample_is_reproducible(tmp_path, sbu_root):
    """Rebuilt from the raw files: every array identical to the bundled one, except the float64 facing angles,
    whose last bit depends on the numpy build's arctan2/mean kernels (seen: 4e-16 rad with numpy 2.4.6)."""
    out, again = tmp_path / "rebuilt.npz", tmp_path / "again.npz"
    assert main(["data", "build-sample", "--raw", str(sbu_root), "--out", str(out)]) == 0
    assert main(["data", "build-sample", "--raw", str(sbu_root), "--out", str(again)]) == 0
    digest = lambda p: hashlib.sha256(p.read_bytes()).hexdigest()  # noqa: E731
    assert digest(out) == digest(again)  # deterministic on one machine, byte for byte
    with np.load(out) as rebuilt, np.load(SAMPLE_DATA) as bundled:
        assert sorted(rebuilt.files) == sorted(bundled.files)
        for name in rebuilt.files:
            if name == "yaw":
                np.testing.assert_allclose(rebuilt[name], bundled[name], rtol=0, atol=1e-12)
            else:
                assert np.array_equal(rebuilt[name], bundled[name]), name


def test_save_load_round_trip(tmp_path, sample_data):
    sub = sample_data.subset([3, 1, 100])
    sub.save(tmp_path / "x.npz")
    back = InteractionDataset.load(tmp_path / "x.npz")
    assert back.sequence_ids == sub.sequence_ids
    np.testing.assert_array_equal(back.leader, sub.leader)
    np.testing.assert_array_equal(back.yaw, sub.yaw)
    np.testing.assert_array_equal(back.canonical(1)[1], sample_data.canonical(1)[1])


def test_summary_prints_the_197_sequence_table_from_the_bundle(capsys):
    assert main(["data", "summary"]) == 0
    out = capsys.readouterr().out
    assert "197 sequences" in out
    assert "shaking_hands" in out and "total" in out
    kicking = next(line for line in out.splitlines() if line.startswith("kicking"))
    assert kicking.split()[1] == "40"


@pytest.mark.shared
def test_summary_on_raw_sbu_and_k3hi(capsys, sbu_root, k3hi_root):
    assert main(["data", "summary", "--data", str(sbu_root)]) == 0
    assert "282 sequences" in capsys.readouterr().out
    assert main(["data", "summary", "--data", str(k3hi_root)]) == 0
    assert "312 sequences" in capsys.readouterr().out


def test_imm_entry_point_help_runs_as_a_program():
    res = subprocess.run([sys.executable, "-m", "imm_model.cli", "--help"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "data" in res.stdout


def test_a_front_end_that_cannot_import_gives_a_one_line_error(monkeypatch, capsys):
    import imm_model.cli as cli

    class BrokenEntry:
        name = "explore"

        def load(self):
            raise ModuleNotFoundError("No module named 'trame'")

    monkeypatch.setattr(cli, "entry_points", lambda group: [BrokenEntry()])
    assert cli.main(["explore", "--port", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("imm explore: error:") and "No module named 'trame'" in err and "\n" not in err
