"""Training and inference on a CUDA device. CI has no GPU, so these skip there; they run wherever torch sees
one (`pytest tests/test_cuda.py`). They were written after a CUDA-only failure: cuDNN refuses to backpropagate
through a recurrent network in eval mode (the frozen label critic's GRU now runs in training mode with its dropout
at 0, the same function, so that cuDNN runs it). Moved to the GPU, every recurrent layer's weights are packed
into one cuDNN buffer; left in separate tensors, cuDNN repacks them on every call and warns."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch

from imm_model.families.gan.trainer import Trainer
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_GAN
from tests.test_training import TINY
from tests.test_training_terms import quick_follower_classifier

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")

# every generator term on: adversarial and class heads, label critic, motion energy
EVERY_TERM = replace(TINY, lambda_critic=0.1, critic_mix_prob=0.5, lambda_energy=0.5,
                     adv_warmup_epochs=0, adv_ramp_epochs=0, model=TINY.model | {"dropout_per_sequence": True})


@pytest.mark.parametrize("cfg", [EVERY_TERM,
                                 replace(TINY, model=TINY.model | {"label_input": False}, discriminator="binary+class")],
                         ids=["every-term", "label-free"])
def test_a_training_epoch_runs_on_cuda(cfg, sample_data, tmp_path, monkeypatch):
    from imm_model import cache

    quick = quick_follower_classifier(sample_data)
    monkeypatch.setattr(cache, "fold_classifier", lambda *a, **k: quick)
    trainer = Trainer(cfg, sample_data, "s04", tmp_path, "cuda")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        row = trainer.train_epoch(0)
        val = trainer.validate()
    assert all(np.isfinite(v) for v in row.values() if isinstance(v, float))
    assert np.isfinite(val["val_afd_m"])
    assert next(trainer.G.parameters()).device.type == "cuda"
    # the recurrent layers' weights sit in one cuDNN buffer each (device.move_module), so no call repacks them
    assert not [w for w in caught if "contiguous chunk" in str(w.message)]


def test_inference_on_cuda_matches_the_cpu(sample_data):
    leader = sample_data.canonical(0)[0]
    label = np.eye(6, dtype=np.float32)[[1, 3]].sum(0)
    cpu = ReactionModel.load(SAMPLE_GAN).synthesize_canonical(leader, label)
    gpu = ReactionModel.load(SAMPLE_GAN, device="cuda").synthesize_canonical(leader, label)
    assert np.abs(cpu - gpu).max() < 1e-3  # metres; TF32 and cuDNN kernels round differently from the CPU
