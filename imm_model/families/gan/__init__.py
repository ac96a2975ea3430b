"""The paper's GAN: the hierarchical Bi-LSTM encoder, the attentive Bi-LSTM decoder and the N+1-way discriminator
(Goel, Men and Ho 2022), kept as the faithful reproduction, with the recipes that make it obey its label."""

from __future__ import annotations

from imm_model.families.base import Family, Trained


def _model_class():
    from imm_model.families.gan.model import GanReactionModel

    return GanReactionModel


def _recipes():
    from imm_model.families.gan.recipes import NAMED

    return NAMED


def _same_recipe(saved, current: dict) -> bool:
    from imm_model.families.gan.recipes import same_recipe

    return same_recipe(saved, current)


def _train(cfg, data, subject, out_dir, device="cpu", resume: bool = False, progress: bool = True) -> Trained:
    """One fold's run: epochs with validation, then (a recipe with `refit`) the refit on training + validation."""
    from imm_model.families.gan.refit import refit
    from imm_model.families.gan.trainer import Trainer

    trainer = Trainer(cfg, data, subject, out_dir, device)
    if resume and (trainer.out / "last.safetensors").exists():
        trainer.resume()
    state = trainer.fit(progress=progress)
    line = (f"best validation AFD {state.best_val:.4f} m at epoch {state.best_epoch} ({state.epoch} epochs) -> "
            f"{trainer.out / 'best.safetensors'}")
    if cfg.refit:
        path = refit(trainer, progress=progress)
        line += f"; refit on training + validation for {state.best_epoch + 1} epochs -> {path}"
    return Trained(line, {"best_epoch": state.best_epoch, "epochs": state.epoch})


FAMILY = Family(name="gan", title="the paper's GAN", model_class=_model_class, recipes=_recipes, train=_train,
                default_recipe="imm", length_option="epochs", same_recipe=_same_recipe)
