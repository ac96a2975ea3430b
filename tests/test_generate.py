"""`imm generate` in batches: folders of leaders, dataset sequences, several labels or the one-hot grid."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from imm_model.cli import main
from imm_model.paths import SAMPLE_GAN

BVH_FIXTURES = Path(__file__).parent / "fixtures" / "bvh"


def test_grid_over_sequences_writes_one_file_per_item(tmp_path, sample_data, capsys):
    ids = sample_data.sequence_ids[:3]
    out = tmp_path / "grid"
    assert main(["generate", "--sequences", ",".join(ids), "--grid", "--out", str(out)]) == 0
    files = sorted(out.glob("*.npz"))
    assert len(files) == 3 * 6 and "3 leaders x 6 labels" in capsys.readouterr().out
    with np.load(out / f"{ids[0].replace('/', '-')}_hugging+1.npz") as z:
        assert z["label"].tolist() == [0, 0, 0, 1, 0, 0] and str(z["sequence_id"]) == ids[0]
        assert z["follower"].shape == (sample_data.lengths[0], 15, 3)
    # the batch gives what one-at-a-time gives
    single = tmp_path / "one.npz"
    assert main(["generate", "--sequence", ids[0], "--label", "hugging=1", "--out", str(single)]) == 0
    with np.load(single) as a, np.load(out / f"{ids[0].replace('/', '-')}_hugging+1.npz") as b:
        np.testing.assert_allclose(a["follower"], b["follower"], atol=1e-4)
    # --raw: the network's follower, bones not held to the bundled model's lengths
    raw = tmp_path / "raw.npz"
    assert main(["generate", "--sequence", ids[0], "--label", "hugging=1", "--raw", "--out", str(raw)]) == 0
    lengths = np.asarray(json.loads(SAMPLE_GAN.with_suffix(".json").read_text())["follower_bone_lengths"])
    with np.load(single) as a, np.load(raw) as r:
        for follower, rigid in ((a["follower"], True), (r["follower"], False)):
            error = np.abs(sample_data.skeleton.bone_lengths(follower) - lengths).max()
            assert (error < 1e-4) if rigid else (error > 0.01)
    # --average-placement: the same motion, the whole follower moved by one offset
    placed = tmp_path / "placed.npz"
    assert main(["generate", "--sequence", ids[0], "--label", "hugging=1", "--average-placement", "--out", str(placed)]) == 0
    with np.load(single) as a, np.load(placed) as p:
        shift = p["follower"] - a["follower"]
        assert np.abs(shift - shift[0, 0]).max() < 1e-4 and np.linalg.norm(shift[0, 0]) > 1e-3


def test_folder_of_bvh_leaders_and_several_labels(tmp_path, capsys):
    out = tmp_path / "bvh"
    args = ["generate", "--leader", str(BVH_FIXTURES), "--label", "kicking=1", "--label", "hugging=1,shaking_hands=1",
            "--format", "bvh", "--out", str(out)]
    assert main(args) == 0
    n = len(list(BVH_FIXTURES.glob("*.bvh")))
    assert len(list(out.glob("*.leader.bvh"))) == 2 * n and len(list(out.glob("*.bvh"))) == 4 * n
    assert main(args) == 2 and "pass --force" in capsys.readouterr().err  # nothing replaced without --force
    assert main(args[:-1] + [str(tmp_path / "x.npz")]) == 2
    assert "need a folder" in capsys.readouterr().err
    assert main(["generate", "--leader", str(tmp_path / "empty_dir_missing"), "--label", "kicking", "--out", str(out / "z")]) == 2
    # a missing leader is named as such, also where --out is a file name
    assert main(["generate", "--leader", str(tmp_path / "missing.bvh"), "--label", "kicking", "--out", str(out / "z.bvh")]) == 2
    assert "missing.bvh: leader file not found" in capsys.readouterr().err
    assert main(["generate", "--sequences", "all", "--out", str(out / "n")]) == 2
    assert "--label" in capsys.readouterr().err
