"""Evaluation: the paper's AFD, per-joint error, the nearest-neighbour baseline and the CLI."""
