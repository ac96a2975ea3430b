"""Shared fixtures. Tests that need ../shared/datasets are marked `shared` and skip without it."""

from __future__ import annotations

import pytest

from imm_model.paths import SAMPLE_DATA, k3hi_raw_root, sbu_raw_root


@pytest.fixture(scope="session")
def sample_data():
    from imm_model.data.dataset import InteractionDataset

    return InteractionDataset.load(SAMPLE_DATA)


@pytest.fixture(scope="session")
def sbu_root():
    root = sbu_raw_root()
    if not root.is_dir():
        pytest.skip(f"raw SBU data not found at {root}")
    return root


@pytest.fixture(scope="session")
def k3hi_root():
    root = k3hi_raw_root()
    if not root.is_dir():
        pytest.skip(f"raw K3HI data not found at {root}")
    return root
