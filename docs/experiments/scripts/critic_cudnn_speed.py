"""`benchmarks/train_speed.py` with the label critic as it ran before it kept cuDNN: in eval mode, with cuDNN turned
off around it (cuDNN backpropagates through a GRU in training mode only). Run it beside train_speed.py on a GPU to
compare the two in the same minutes.

    python docs/experiments/scripts/critic_cudnn_speed.py --config imm-steer --device cuda --threads 1 --epochs 3
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import torch

from imm_model.training import critic


def eval_mode_critic(self, classifier) -> None:
    self.classifier = classifier.eval().requires_grad_(False)


def loss_without_cudnn(self, follower, lengths, target):
    with torch.backends.cudnn.flags(enabled=False):
        return torch.nn.functional.cross_entropy(self.classifier(follower, lengths), target, reduction="none").mean()


if __name__ == "__main__":
    critic.LabelCritic.__init__ = eval_mode_critic
    critic.LabelCritic.loss = loss_without_cudnn
    sys.argv = ["train_speed.py", *sys.argv[1:]]
    runpy.run_path(str(Path(__file__).parents[3] / "benchmarks" / "train_speed.py"), run_name="__main__")
