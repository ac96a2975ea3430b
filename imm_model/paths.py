"""Where the bundled files and the shared raw datasets live."""

from __future__ import annotations

import os
from importlib import metadata
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
DISTRIBUTION = "imm-studio"
_MARKER = "sbu_interactions.npz"


def _installed_sample_dir() -> Path | None:
    """sample_data/ as an installed wheel placed it: pyproject.toml maps it to share/imm-studio/sample_data
    (data-files), whose prefix depends on the install scheme (venv, --user, system), so ask the
    distribution's own file list where it went."""
    try:
        files = metadata.distribution(DISTRIBUTION).files or ()
    except metadata.PackageNotFoundError:
        return None
    for f in files:
        if f.name == _MARKER and f.parent.name == "sample_data":
            return Path(str(f.locate())).resolve().parent
    return None


def _sample_dir() -> Path:
    """The bundled data, models and judge: $IMM_SAMPLE_DIR, else sample_data/ at the top of the checkout,
    else the copy an installed wheel carries."""
    if os.environ.get("IMM_SAMPLE_DIR"):
        return Path(os.environ["IMM_SAMPLE_DIR"])
    checkout = REPO_ROOT / "sample_data"
    if (checkout / _MARKER).is_file():
        return checkout
    return _installed_sample_dir() or checkout


SAMPLE_DIR = _sample_dir()
SAMPLE_DATA = SAMPLE_DIR / "sbu_interactions.npz"
SAMPLE_GAN = SAMPLE_DIR / "imm_sbu.safetensors"  # the paper's GAN (`imm-steer`), one click away in the studio
# the reaction diffusion model (`imm-diffusion`, 7 sampler steps): the default's teacher, which makes its long takes and
# live reactions
SAMPLE_DIFFUSION = SAMPLE_DIR / "imm_diffusion.safetensors"
# a 2-step student of it (`imm-diffusion-student`), the default model: ReactionModel.load(), `imm generate` and the studio
# use it when none is given, its long takes and live reactions made by its teacher (docs/experiments/default-student.md)
SAMPLE_STUDENT = SAMPLE_DIR / "imm_diffusion_student.safetensors"
SAMPLE_DEFAULT = SAMPLE_STUDENT
# the diffusion model trained with a label per body part (`imm-diffusion-parts`): experimental, not opened by the studio
# by default (the default model takes a label per body part too, and measured the same on part labels: its model card)
SAMPLE_PARTS = SAMPLE_DIR / "imm_diffusion_parts.safetensors"
SAMPLE_RETRIEVAL = SAMPLE_DIR / "imm_retrieval.safetensors"  # 1-NN retrieval from the bundled data, s04 held out
SAMPLE_JUDGE = SAMPLE_DIR / "follower_judge.safetensors"  # the studio's "reads as" classifier (imm_model/reads_as.py)
# the body-part judges: the follower's upper and lower body read alone, the studio's reading per part of a mix
SAMPLE_UPPER_JUDGE = SAMPLE_DIR / "upper_judge.safetensors"
SAMPLE_LOWER_JUDGE = SAMPLE_DIR / "lower_judge.safetensors"
# the bundled models by the names the studio gives them, in its switch's order (the first, the default, opens it)
SAMPLE_MODELS = {"diffusion": SAMPLE_DEFAULT, "gan": SAMPLE_GAN, "retrieval": SAMPLE_RETRIEVAL}


def shared_datasets() -> Path:
    """Raw datasets: $IMM_SHARED_DATASETS, else ../shared/datasets beside the checkout."""
    env = os.environ.get("IMM_SHARED_DATASETS")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "datasets"


def sbu_raw_root() -> Path:
    return shared_datasets() / "sbu_kinect_interaction"


def k3hi_raw_root() -> Path:
    return shared_datasets() / "k3hi"
