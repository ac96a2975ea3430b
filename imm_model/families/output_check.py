"""A reaction model's outputs checked once, when it is loaded. A checkpoint's digest proves its weights are the ones
saved, not that they are sane: weights of 1e30 load, and every follower they synthesize stands 1e32 m away. So
`check_model_outputs` synthesizes a short reaction to a bundled leader or two and refuses (one line naming the
file) a model whose follower is not finite or stands farther from its leader than any interaction does. It costs a
few milliseconds: each family draws as cheaply as it can (`ReactionModel.probing`: no clean-up; the diffusion model
samples in one step)."""

from __future__ import annotations

import functools

import numpy as np

from imm_model.errors import CheckpointError

MAX_DISTANCE_M = 10.0  # a follower joint from its leader's centre: two people interacting stand within a few metres
PROBE_FRAMES = 16
PROBE_SEQUENCES = (0, -1)  # the bundle's first and last sequences (of different classes)


@functools.cache
def _probe_leaders(joint_names: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """The first PROBE_FRAMES frames of the bundled leaders PROBE_SEQUENCES (canonical, float32); none when the
    bundled data is missing or has another skeleton (there is nothing to probe such a model with)."""
    import json

    from imm_model.data.npz import read_npz
    from imm_model.errors import IMMError
    from imm_model.paths import SAMPLE_DATA

    try:
        arrays = read_npz(SAMPLE_DATA, ["leader", "lengths", "metadata"], 256_000_000, "interaction bundle")
        skeleton = json.loads(arrays["metadata"].tobytes())["skeleton"]
    except (IMMError, ValueError, KeyError, TypeError):
        return ()
    if tuple(skeleton.get("joint_names", ())) != joint_names:
        return ()
    starts = np.concatenate([[0], np.cumsum(arrays["lengths"])[:-1]])
    return tuple(arrays["leader"][starts[i]: starts[i] + PROBE_FRAMES].astype(np.float32) for i in PROBE_SEQUENCES)


def check_model_outputs(model):
    """Refuse (CheckpointError) a loaded ReactionModel whose follower to a bundled leader is not finite or stands
    more than MAX_DISTANCE_M from it -> the model, as it was."""
    leaders = _probe_leaders(tuple(model.skeleton.joint_names))
    with model.probing():  # the network's own follower, as cheaply as the family can draw it
        for k, leader in enumerate(leaders):
            label = np.zeros((1, len(model.class_names)), np.float32)
            label[0, k % label.shape[1]] = 1.0
            with np.errstate(all="ignore"):  # overflowing weights are what is looked for, not a warning
                follower = model.synthesize_batch_canonical([leader], label, [0])[0]
                centre = leader.mean(axis=1, keepdims=True)
                distance = float(np.max(np.linalg.norm(follower - centre, axis=-1)))
            if not distance <= MAX_DISTANCE_M:  # NaN too
                raise CheckpointError(f"{model.path}: its follower to a bundled leader stands {distance:.3g} m from the "
                                      f"leader (up to {MAX_DISTANCE_M:g} m is expected): broken weights?")
    return model
