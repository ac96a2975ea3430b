"""What a synthesized reaction reads as: a follower-only reaction classifier's class probabilities.

The studio shows them beside the label sliders, so a user sees whether a mix reads as intended. The classifier
is the evaluation's independent judge (model/classifier.py FOLLOWER_JUDGE: temporal conv, trained on real
followers only, never a training critic), trained on the same subjects as the bundled model (fold s04 held out)
and bundled as sample_data/follower_judge.safetensors (`imm data build-judge`). A conv classifier runs
in numpy (model/numpy_runtime.py: the studio never imports torch for it); a GRU one on torch. The body-part judges
(UPPER_JUDGE / LOWER_JUDGE, sample_data/upper_judge and lower_judge.safetensors, `imm data build-judge --inputs upper`)
load alike and read the follower's part (model/body_parts.py): a mix by body part reads per part.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imm_model.errors import CheckpointError
from imm_model.model.body_parts import body_part_view

# A class asked for reads in the reaction when it gets at least this share of the probability: a two-class mix reads
# as mixed when both members do (the mix target; evaluation/report.py counts the pairs).
MIX_SHARE = 0.25
FOLLOWER_INPUTS = ("follower", "upper", "lower")  # the follower whole, or a body part of it


class ReadsAs:
    def __init__(self, classifier, class_names: tuple[str, ...], meta: dict):
        self.classifier = classifier  # a NumpyConvClassifier, or a torch MotionClassifier in eval mode
        self.class_names = class_names
        self.meta = meta

    @classmethod
    def load(cls, path: Path | str) -> ReadsAs:
        """A classifier file written by `imm data build-judge` (or a cache entry); any problem -> CheckpointError."""
        from imm_model.checkpoint import check_state, load_checkpoint
        from imm_model.model.classifier_config import ClassifierConfig
        from imm_model.model.numpy_runtime import NumpyConvClassifier

        arrays, meta = load_checkpoint(path, framework="np")
        unreadable = [name for name, array in arrays.items() if array.dtype.kind == "f" and not np.isfinite(array).all()]
        if unreadable:  # its probabilities would all be NaN: the panel would read nothing, silently
            raise CheckpointError(f"{path}: weights that are not finite numbers ({', '.join(sorted(unreadable)[:3])}"
                                  f"{', ...' if len(unreadable) > 3 else ''})")
        try:
            cfg = ClassifierConfig.from_dict(meta["config"])
            names = tuple(str(n) for n in meta["class_names"])
            pose_dim = int(arrays["mean"].shape[0]) // 2
        except (KeyError, TypeError, ValueError) as err:
            raise CheckpointError(f"{path}: not a reaction classifier ({type(err).__name__}: {err})") from None
        if cfg.inputs not in FOLLOWER_INPUTS:
            raise CheckpointError(f"{path}: a {cfg.inputs} classifier; the studio needs a follower-only one (whole or a body part)")
        if cfg.arch == "conv" and not cfg.start_centred:  # the numpy runtime reads positions as they come
            check_state(arrays, NumpyConvClassifier.expected_shapes(cfg.hidden, cfg.features, pose_dim, len(names)), "classifier", path)
            return cls(NumpyConvClassifier(arrays), names, meta)
        return cls(_torch_classifier(cfg, arrays, pose_dim, len(names), path), names, meta)

    @property
    def part(self) -> str | None:
        """"upper" or "lower" for a body-part judge, None for the whole-follower one."""
        inputs = self.meta["config"]["inputs"]
        return inputs if inputs != "follower" else None

    def probabilities(self, follower: np.ndarray) -> np.ndarray:
        """(T, J, 3) canonical metres -> (C,) class probabilities (a part judge reads its part of it)."""
        x = np.asarray(follower, np.float32)
        if self.part is not None:
            x = body_part_view(x, self.part)
        x = x.reshape(len(x), -1)
        if hasattr(self.classifier, "probabilities"):
            return self.classifier.probabilities(x)
        import torch

        with torch.inference_mode():
            logits = self.classifier(torch.from_numpy(x[None]), torch.tensor([len(x)]))
        return torch.softmax(logits, -1)[0].numpy().astype(np.float64)


def _torch_classifier(cfg, arrays: dict[str, np.ndarray], pose_dim: int, num_classes: int, path):
    import torch

    from imm_model.checkpoint import load_module_state
    from imm_model.model.classifier import MotionClassifier

    model = MotionClassifier(cfg, pose_dim, num_classes)
    load_module_state(model, {k: torch.from_numpy(v) for k, v in arrays.items()}, "classifier", path)
    return model.eval()
