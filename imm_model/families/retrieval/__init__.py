"""Nearest-neighbour retrieval: a real training follower for each leader and label (the paper's NN baseline, as a
model every learned family is compared with)."""

from __future__ import annotations

from imm_model.families.base import Family, Trained


def _model_class():
    from imm_model.families.retrieval.model import RetrievalReactionModel

    return RetrievalReactionModel


def _recipes():
    from imm_model.families.retrieval.recipes import NAMED

    return NAMED


def _train(cfg, data, subject, out_dir, device="cpu", resume: bool = False, progress: bool = True) -> Trained:
    """Nothing to learn: the fold's checkpoint names the data it retrieves from and the subject it never sees."""
    from pathlib import Path

    from imm_model.families.retrieval.model import RetrievalReactionModel

    final = Path(out_dir) / "final.safetensors"
    final.parent.mkdir(parents=True, exist_ok=True)
    model = RetrievalReactionModel.build(data, subject)
    model.save(final)
    held_out = f", {subject} held out" if subject else ""
    return Trained(f"retrieves from {sum(map(len, model.pairs))} training sequences{held_out} -> {final}", {})


FAMILY = Family(name="retrieval", title="1-NN retrieval", model_class=_model_class, recipes=_recipes, train=_train,
                default_recipe="retrieval", length_option=None)
