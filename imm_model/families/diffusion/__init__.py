"""The reaction diffusion model: a transformer denoiser over the follower's frames and a DDIM sampler that composes
the signed multi-hot label (+1 conjunction, -1 negation); a seed is a variation."""

from __future__ import annotations

from imm_model.families.base import Family, Trained


def _model_class():
    from imm_model.families.diffusion.model import DiffusionReactionModel

    return DiffusionReactionModel


def _recipes():
    from imm_model.families.diffusion.recipes import NAMED

    return NAMED


def _train(cfg, data, subject, out_dir, device="cpu", resume: bool = False, progress: bool = True) -> Trained:
    if cfg.teacher and resume:
        raise ValueError("--resume: a student or a live reactor is trained in one go; run it again without --resume")
    if cfg.live_pool:
        from imm_model.families.diffusion.live_train import train_live

        return train_live(cfg, data, subject, out_dir, device, progress)
    if cfg.teacher:
        from imm_model.families.diffusion.distill import distill

        return distill(cfg, data, subject, out_dir, device, progress)
    from imm_model.families.diffusion.trainer import train

    return train(cfg, data, subject, out_dir, device, resume, progress)


FAMILY = Family(name="diffusion", title="the diffusion model", model_class=_model_class, recipes=_recipes, train=_train,
                default_recipe="imm-diffusion", length_option="steps")
