"""Where the bundled files and the shared raw datasets live."""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
# The bundled sample data and models ship inside the package (a wheel has them too); $IMM_SAMPLE_DIR overrides.
SAMPLE_DIR = Path(os.environ.get("IMM_SAMPLE_DIR") or Path(__file__).resolve().parent / "sample_data")
SAMPLE_DATA = SAMPLE_DIR / "sbu_interactions.npz"
SAMPLE_CHECKPOINT = SAMPLE_DIR / "imm_sbu.safetensors"
SAMPLE_JUDGE = SAMPLE_DIR / "follower_judge.safetensors"  # the studio's "reads as" classifier (imm_model/reads_as.py)


def shared_datasets() -> Path:
    """Raw datasets: $IMM_SHARED_DATASETS, else ../shared/datasets beside the checkout."""
    env = os.environ.get("IMM_SHARED_DATASETS")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "datasets"


def sbu_raw_root() -> Path:
    return shared_datasets() / "sbu_kinect_interaction"


def k3hi_raw_root() -> Path:
    return shared_datasets() / "k3hi"
