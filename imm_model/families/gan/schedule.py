"""Schedules over epochs: the warm-up and ramp every auxiliary loss weight follows, and the learning-rate decay on
validation plateaus (computed from the history alone, so a resumed run decays exactly as an uninterrupted one)."""

from __future__ import annotations

import math

from imm_model.families.gan.recipes import TrainConfig


def adversarial_weight(cfg: TrainConfig, epoch: int, weight: float | None = None) -> float:
    """0 during warm-up, then a linear ramp to `weight` (default lambda_adv; epochs count from 0)."""
    weight = cfg.lambda_adv if weight is None else weight
    if epoch < cfg.adv_warmup_epochs:
        return 0.0
    if cfg.adv_ramp_epochs <= 0:
        return weight
    return weight * min(1.0, (epoch - cfg.adv_warmup_epochs + 1) / cfg.adv_ramp_epochs)


def lr_scale(cfg: TrainConfig, history: list[dict], select_from: int) -> float:
    """Learning-rate multiplier for the next epoch, from the validation history alone (so a resumed run
    decays exactly as an uninterrupted one): lr_decay_factor ** (plateaus of lr_decay_patience epochs)."""
    if cfg.lr_decay_patience <= 0:
        return 1.0
    best, since, decays = math.inf, 0, 0
    for row in history:
        if row["epoch"] < select_from:
            continue
        if row["val_afd_m"] < best:
            best, since = row["val_afd_m"], 0
        else:
            since += 1
            if since >= cfg.lr_decay_patience:
                decays, since = decays + 1, 0
    return cfg.lr_decay_factor ** decays
