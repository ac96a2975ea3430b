"""What a synthesized reaction reads as: a follower-only reaction classifier's class probabilities.

The studio shows them beside the label sliders, so a user sees whether a mix reads as intended. The classifier
is the evaluation's independent judge (model/classifier.py FOLLOWER_JUDGE: temporal conv, trained on real
followers only, never a training critic), trained on the same subjects as the bundled model (fold s04 held out)
and bundled as imm_model/sample_data/follower_judge.safetensors (`imm data build-judge`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.errors import CheckpointError


class ReadsAs:
    def __init__(self, classifier, class_names: tuple[str, ...], meta: dict):
        self.classifier = classifier.eval()
        self.class_names = class_names
        self.meta = meta

    @classmethod
    def load(cls, path: Path | str) -> ReadsAs:
        """A classifier file written by `imm data build-judge` (or a cache entry); any problem -> CheckpointError."""
        from imm_model.checkpoint import load_checkpoint, load_module_state
        from imm_model.model.classifier import ClassifierConfig, MotionClassifier

        tensors, meta = load_checkpoint(path)
        try:
            cfg = ClassifierConfig.from_dict(meta["config"])
            names = tuple(str(n) for n in meta["class_names"])
            pose_dim = int(tensors["mean"].shape[0]) // 2
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(f"{path}: not a reaction classifier ({type(err).__name__}: {err})") from None
        if cfg.inputs != "follower":
            raise CheckpointError(f"{path}: a {cfg.inputs} classifier; the studio needs a follower-only one")
        model = MotionClassifier(cfg, pose_dim, len(names))
        load_module_state(model, tensors, "classifier", path)
        return cls(model, names, meta)

    def probabilities(self, follower: np.ndarray) -> np.ndarray:
        """(T, J, 3) canonical metres -> (C,) class probabilities."""
        import torch

        x = torch.as_tensor(np.asarray(follower, np.float32).reshape(1, len(follower), -1))
        with torch.inference_mode():
            return torch.softmax(self.classifier(x, torch.tensor([len(follower)])), -1)[0].numpy().astype(np.float64)
