"""Colors shared by the 3D view, the legend, the charts and the latent plot.

Characters follow the paper's figures (leader blue, ground truth red, synthesized green). Classes
use the rest of the tab10 palette, so a class color is never mistaken for a character.
"""

from __future__ import annotations

LEADER = "#1f5fd6"
GROUND_TRUTH = "#d62728"
SYNTHESIZED = "#2ca02c"
PINNED = "#7b1fa2"  # A/B: the pinned mix's follower, beside the current (green) one
COMPARED = "#00897b"  # other models' followers, beside the current model's (green) one
WARNING = "#ff6f00"  # limbs of the two bodies that interpenetrate (explorer/rendering/scene.py ContactOverlay)

CHARACTERS = {"leader": LEADER, "ground_truth": GROUND_TRUTH, "synthesized": SYNTHESIZED}
CHARACTER_TITLES = {"leader": "Leader (A)", "ground_truth": "Ground truth (B)", "synthesized": "Synthesized (B)"}

CLASS_COLORS = ["#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf", "#7f7f7f", "#aec7e8"]


def class_color(index: int) -> str:
    return CLASS_COLORS[index % len(CLASS_COLORS)]


def display_name(class_name: str) -> str:
    return class_name.replace("_", " ")
