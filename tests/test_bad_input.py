"""Every malformed input gets a one-line error naming the file (and line); one bad file never aborts the rest.

The malformed files here are synthetic on purpose: each is a real fixture with one defect injected.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from imm_model.cli import main
from imm_model.data import load_k3hi, load_sbu
from imm_model.data.dataset import InteractionDataset
from imm_model.data.sbu import parse_skeleton_file
from imm_model.errors import DataFormatError

FIXTURES = Path(__file__).parent / "fixtures"
GOOD = FIXTURES / "sbu/s01s02/03/001/skeleton_pos.txt"


def _lines() -> list[str]:
    return GOOD.read_text().splitlines()


def _write(tmp_path: Path, lines: list[str], rel: str = "s01s02/03/001") -> Path:
    path = tmp_path / rel / "skeleton_pos.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\r\n".join(lines) + ("\r\n" if lines else ""))
    return path


def _replace(line: str, index: int, value: str) -> str:
    fields = line.split(",")
    fields[index] = value
    return ",".join(fields)


CASES = {
    "wrong column count": (lambda ls: ls[:2] + [ls[2] + ",0.5"] + ls[3:], r":3: expected 91 comma-separated values, found 92"),
    "missing columns": (lambda ls: ls[:1] + [",".join(ls[1].split(",")[:46])] + ls[2:], r":2: expected 91 .* found 46"),
    "non-numeric": (lambda ls: ls[:3] + [_replace(ls[3], 10, "abc")] + ls[4:], r":4: non-numeric value 'abc'"),
    "NaN": (lambda ls: ls[:4] + [_replace(ls[4], 7, "nan")] + ls[5:], r":5: NaN or infinite value"),
    "inf": (lambda ls: [_replace(ls[0], 90, "inf")] + ls[1:], r":1: NaN or infinite value"),
    "empty file": (lambda ls: [], r"empty file"),
    "one frame": (lambda ls: ls[:1], r"only 1 frame; at least 2"),
}


@pytest.mark.parametrize("case", CASES)
def test_malformed_sbu_file_has_a_one_line_error_naming_file_and_line(tmp_path, case):
    mutate, pattern = CASES[case]
    path = _write(tmp_path, mutate(_lines()))
    with pytest.raises(DataFormatError, match=pattern) as info:
        parse_skeleton_file(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message


def test_binary_garbage_and_missing_file(tmp_path):
    path = tmp_path / "s01s02/03/001/skeleton_pos.txt"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"\x89PNG\x00\xff\xfe")
    with pytest.raises(DataFormatError, match="not a text file"):
        parse_skeleton_file(path)
    with pytest.raises(DataFormatError, match="nope.txt: skeleton file not found"):
        parse_skeleton_file(tmp_path / "nope.txt")


def test_one_bad_file_is_skipped_and_reported_unless_strict(tmp_path):
    root = tmp_path / "sbu"
    shutil.copytree(FIXTURES / "sbu", root)
    _write(root, _lines()[:1] + [_replace(_lines()[1], 5, "x")], rel="s05s02/08/002")
    _write(root, _lines(), rel="s05s02/11/001")  # unknown class folder
    result = load_sbu(root, classes="all")
    assert len(result) == 3  # the three good fixtures still load
    reasons = " | ".join(r for _, r in result.skipped)
    assert len(result.skipped) == 2
    assert "s05s02/08/002/skeleton_pos.txt:2: non-numeric value 'x'" in reasons
    assert "unknown class folder '11'" in reasons
    assert "skipped 2 file(s)" in result.report()
    with pytest.raises(DataFormatError):
        load_sbu(root, classes="all", strict=True)


def test_unknown_paths_and_classes(tmp_path):
    with pytest.raises(DataFormatError, match="SBU data folder not found"):
        load_sbu(tmp_path / "missing")
    with pytest.raises(DataFormatError, match="no sXXsYY"):
        load_sbu(tmp_path)
    with pytest.raises(ValueError, match="unknown SBU classes"):
        load_sbu(FIXTURES / "sbu", classes=("dancing",))
    with pytest.raises(DataFormatError, match="K3HI folder not found"):
        load_k3hi(tmp_path)


def test_unreadable_and_malformed_mat_files(tmp_path):
    root = tmp_path / "k3hi"
    shutil.copytree(FIXTURES / "k3hi", root)
    bad = root / "Skeletons/kicking/2"
    bad.mkdir()
    (bad / "skeleton_A.mat").write_bytes(b"MATLAB 5.0 MAT-file, garbage" + b"\x00" * 20)
    shutil.copy(root / "Skeletons/kicking/1/skeleton_B.mat", bad / "skeleton_B.mat")
    result = load_k3hi(root)
    assert len(result) == 1 and len(result.skipped) == 1
    assert "kicking/2/skeleton_A.mat: unreadable .mat file" in result.skipped[0][1]
    from scipy.io import savemat

    savemat(bad / "skeleton_A.mat", {"curve_B": [[1.0, 2.0]] * 44})
    with pytest.raises(DataFormatError, match=r"curve_B has shape \(44, 2\), expected \(45, T\)"):
        load_k3hi(root, strict=True)


def test_corrupt_bundle_is_a_one_line_error_and_cli_exits_2(tmp_path, capsys):
    bad = tmp_path / "broken.npz"
    bad.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(DataFormatError, match=r"unreadable .npz \(not a zip"):
        InteractionDataset.load(bad)
    assert main(["data", "summary", "--data", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("imm data: error:") and "broken.npz" in err and "\n" not in err
    assert main(["data", "summary", "--data", str(tmp_path / "nowhere")]) == 2
    assert "no such file or folder" in capsys.readouterr().err


def test_outputs_never_replace_files_or_inputs_and_never_write_nan(tmp_path, capsys):
    """--out over an existing file needs --force; an input is never the output; NaN weights are refused at load."""
    import torch

    from imm_model.checkpoint import load_checkpoint, save_checkpoint
    from imm_model.paths import SAMPLE_GAN

    out = tmp_path / "x.npz"
    args = ["generate", "--sequence", "s01s02/03/001", "--label", "kicking=1", "--out", str(out)]
    assert main(args) == 0
    first = out.read_bytes()
    assert main(args) == 2 and "pass --force" in capsys.readouterr().err and out.read_bytes() == first
    assert main(args + ["--force"]) == 0
    assert main(["generate", "--leader", str(out), "--label", "kicking=1", "--out", str(out), "--force"]) == 2
    assert "an input of this command" in capsys.readouterr().err
    tensors, meta = load_checkpoint(SAMPLE_GAN)
    key = next(k for k in tensors if k.startswith("generator.") and tensors[k].is_floating_point())
    tensors[key] = torch.full_like(tensors[key], float("nan"))
    save_checkpoint(tmp_path / "nan.safetensors", tensors, meta)
    assert main(["generate", "--sequence", "s01s02/03/001", "--label", "kicking=1", "--out", str(tmp_path / "y.npz"),
                 "--checkpoint", str(tmp_path / "nan.safetensors")]) == 2
    assert "not finite" in capsys.readouterr().err and not (tmp_path / "y.npz").exists()
    (tmp_path / "r.json").write_text("{}")
    assert main(["evaluate", "--json", str(tmp_path / "r.json"), "--quiet"]) == 2  # refused before evaluating
    assert "pass --force" in capsys.readouterr().err
