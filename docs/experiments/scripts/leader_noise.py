"""Score the diffusion model with annealed noise on its leader input (CADS, Sadat et al. ICLR 2024), through
diffusion_fold.py: at noise levels t/(T-1) above tau1 the leader the network reads is sqrt(g) * A + noise * sqrt(1 - g)
* z, g falling linearly from 1 at tau1 to 0 at tau2, rescaled per sequence to A's mean and spread (psi = 1); z is drawn
per step from the sampler seed. An experiment, not a sampler option: the leader in a limited interval
(`Guidance.leader_below`) replaced it (docs/experiments/diffusion-variations.md).

    python docs/experiments/scripts/leader_noise.py --tau 0.6 0.9 --noise 0.5 -- \\
        --checkpoint sample_data/imm_diffusion.safetensors --fold s04 --guided-below 0.3 --out rows.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from imm_model.families.diffusion import sampler as ds

sys.path.insert(0, str(Path(__file__).parent))
import diffusion_fold  # noqa: E402


def moments(a: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sequence mean and spread of (B, T, D) over its valid frames (m: (B, T, 1))."""
    count = m.sum((1, 2), keepdims=True) * a.shape[2]
    mean = (a * m).sum((1, 2), keepdims=True) / count
    return mean, np.sqrt((((a - mean) * m) ** 2).sum((1, 2), keepdims=True) / count) + 1e-6


def annealed_leader_sampler(model, tau1: float, tau2: float, noise: float):
    """A sampler for `model.sampler` whose network call reads the annealed noisy leader (numpy runtime only)."""
    steps = model.config.diffusion_steps

    def sampler(clean, x, mask, labels, start_noise, guidance, steps_, seeds, **network):
        m = mask[..., None].astype(np.float32)

        def denoise(x_t, step, leader_on, label, label_on):
            g = float(np.clip((tau2 - step / (steps - 1)) / (tau2 - tau1), 0, 1))
            if g >= 1.0:
                return clean(x_t, step, leader_on, label, label_on)
            z = np.stack([np.random.default_rng((int(s), 7, int(step))).standard_normal(x.shape[1:]) for s in seeds])
            y = np.sqrt(g) * x + noise * np.sqrt(1 - g) * z.astype(np.float32)
            (mean0, sd0), (mean1, sd1) = moments(x, m), moments(y, m)
            y = (((y - mean1) / sd1 * sd0 + mean0) * m).astype(np.float32)
            reps = len(x_t) // len(x)
            return model.fast.conditioned(np.tile(y, (reps, 1, 1)), leader_on, label, label_on, np.tile(mask, (reps, 1)))(x_t, step)

        return ds.sample(denoise, x, mask, labels, start_noise, guidance, steps_, seeds=seeds, **network)

    return sampler


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tau", type=float, nargs=2, required=True, help="noise levels where the annealing starts and ends")
    ap.add_argument("--noise", type=float, required=True, help="the noise's scale before the rescaling")
    ap.add_argument("rest", nargs=argparse.REMAINDER, help="-- diffusion_fold.py's arguments")
    args = ap.parse_args()
    def adapt(model) -> None:
        if model.settings.spread:
            model.spread = 0.0  # the annealing is the only noise on the leader
        model.sampler = annealed_leader_sampler(model, *args.tau, args.noise)

    diffusion_fold.main([a for a in args.rest if a != "--"], adapt=adapt,
                        extra={"leader_noise": {"tau": args.tau, "noise": args.noise}})


if __name__ == "__main__":
    main()
