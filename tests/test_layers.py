"""The structure check (imm_model/devtools/layers.py): the project's imports go down the layers with no cycle, and
the check itself finds an upward import, a cycle and an unplaced module, wherever the import is written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from imm_model.devtools import layers


def test_the_projects_imports_go_down_the_layers_without_a_cycle():
    found, n_modules, n_imports = layers.problems()
    assert found == []
    assert n_modules > 50 and n_imports > 200  # it did read the project


def test_the_command_prints_a_summary_and_exits_0():
    done = subprocess.run([sys.executable, "-m", "imm_model.devtools.layers"], capture_output=True, text=True, timeout=120,
                          cwd=layers.repo_root())
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.startswith("layers: ") and "no import cycle" in done.stdout


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_the_check_finds_upward_imports_cycles_and_unplaced_modules(tmp_path):
    _write(tmp_path, {
        "imm_model/__init__.py": "",
        "imm_model/errors.py": "",
        "imm_model/data/__init__.py": "",
        # an upward import hidden in a function, and a relative one
        "imm_model/data/splits.py": "def f():\n    from imm_model.training.config import X\n",
        "imm_model/data/reader.py": "from ..evaluation import metrics\n",
        "imm_model/training/__init__.py": "",
        "imm_model/training/config.py": "from imm_model.training import trainer\n",
        "imm_model/training/trainer.py": "import imm_model.training.config\nfrom imm_model.errors import E\n",
        "imm_model/evaluation/__init__.py": "",
        "imm_model/evaluation/metrics.py": "import numpy\n",
        "imm_model/newthing.py": "",
        "imm_model/data/__main__.py": "from imm_model.cli import main\n",  # an entry point may import the top
        "imm_model/cli.py": "",
        "explorer/__init__.py": "",
        "explorer/ui/app.py": "from imm_model.evaluation.metrics import afd\n",
    })
    found, n_modules, _ = layers.problems(tmp_path)
    text = "\n".join(found)
    assert n_modules == 15
    assert "imm_model/data/splits.py:2: imm_model.data.splits (data) imports imm_model.training.config (training)" in text
    assert "imm_model/data/reader.py:1: imm_model.data.reader (data) imports imm_model.evaluation.metrics" in text
    assert "import cycle: imm_model.training.config <-> imm_model.training.trainer" in text
    assert "imm_model.newthing: in no layer" in text
    assert len(found) == 4  # the entry point, the studio and the downward imports pass
