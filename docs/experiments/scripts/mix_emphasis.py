"""Train a default-recipe student whose teacher pool asks for two-class mixes more often: the share of pool rows that
perform two classes (distill.py LABEL_KINDS' third kind) set to MIX_SHARE, the other kinds keeping their proportions
to one another. Everything else is `imm train` (any further arguments go to it, e.g. a --config of overrides).

    OMP_NUM_THREADS=1 python docs/experiments/scripts/mix_emphasis.py --mix-share 0.5 -- \\
        --config imm-diffusion-student --fold s04 --threads 1 --quiet --out runs/mix-0.5

docs/experiments/mix-emphasis.md records what it measured.
"""

from __future__ import annotations

import argparse
import sys

from imm_model import cli
from imm_model.families.diffusion import distill

MIX_KIND = "two classes performed, each 0.3..1.5"


def with_mix_share(kinds: tuple, share: float) -> tuple:
    """LABEL_KINDS with the two-class kind at `share` and the other kinds scaled to fill the rest."""
    rest = sum(s for name, s in kinds if name != MIX_KIND)
    return tuple((name, share if name == MIX_KIND else s * (1 - share) / rest) for name, s in kinds)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mix-share", type=float, required=True, help="share of the pool's rows performing two classes")
    p.add_argument("train", nargs=argparse.REMAINDER, help="-- then `imm train`'s arguments")
    args = p.parse_args()
    if not 0 <= args.mix_share <= 1:
        p.error(f"--mix-share must lie in 0..1, not {args.mix_share}")
    distill.LABEL_KINDS = with_mix_share(distill.LABEL_KINDS, args.mix_share)
    print("pool label kinds:", ", ".join(f"{name} {share:.3f}" for name, share in distill.LABEL_KINDS), flush=True)
    rest = args.train[1:] if args.train[:1] == ["--"] else args.train
    return cli.main(["train", *rest])


if __name__ == "__main__":
    sys.exit(main())
