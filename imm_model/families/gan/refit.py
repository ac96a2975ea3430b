"""The refit after model selection: retrain on the fold's training + validation sequences for the selected number
of epochs, since no validation is left to select on."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.checkpoint import save_checkpoint
from imm_model.families.gan.schedule import lr_scale
from imm_model.families.gan.trainer import FoldState, Trainer, check_finite


def refit(selection: Trainer, progress: bool = True) -> Path:
    """Retrain on the fold's training + validation sequences for `selection`'s best epoch + 1 epochs.

    A fresh Trainer with the same config and seed (so the same initial weights and normalization), its
    learning rate following the selection run's decays epoch by epoch (`lr_scale` of its history). There is
    no validation left to select on, so the last epoch's (EMA) generator is saved as final.safetensors.
    Deterministic, so an interrupted refit is simply run again.
    """
    from tqdm import tqdm

    if selection.state.best_epoch < 0:
        raise ValueError("refit needs a finished selection run (no best epoch yet)")
    epochs = selection.state.best_epoch + 1
    history = selection.state.history
    t = Trainer(selection.cfg, selection.data, selection.subject, selection.out, selection.device)
    t.train_idx = np.concatenate([t.train_idx, t.val_idx])
    for epoch in tqdm(range(epochs), desc=f"refit {t.subject or 'all'}", disable=not progress, leave=False, dynamic_ncols=True):
        check_finite(t.train_epoch(epoch, lr_multiplier=lr_scale(t.cfg, history[:epoch], selection.select_from)), epoch, t.out)
    t.state = FoldState(epoch=epochs, best_val=selection.state.best_val, best_epoch=selection.state.best_epoch)
    path = t.out / "final.safetensors"
    save_checkpoint(path, t.weights(), t.meta("final") | {"refit": {"epochs": epochs, "sequences": len(t.train_idx)}})
    return path

