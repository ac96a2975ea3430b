"""SHA-256 of every output the bundled models give through the public API, to show that a change of code leaves the
outputs bit-identical.

    python docs/experiments/scripts/output_digests.py --out digests.json        # before the change
    python docs/experiments/scripts/output_digests.py --compare digests.json    # after: prints how many differ

Covers each bundled checkpoint (paths.SAMPLE_MODELS and the part-trained SAMPLE_PARTS) on every sequence of the
bundled data (its world leader under its own class, seed 0),
a two-class mix and an avoid on every tenth sequence, three seeds of the diffusion model on every tenth sequence,
the canonical batch path on all sequences at once, the latent embedding of every tenth sequence, and the BVH leaders
in tests/fixtures/bvh.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from imm_model.data.bvh import read_bvh
from imm_model.data.dataset import InteractionDataset
from imm_model.inference import ReactionModel
from imm_model.paths import REPO_ROOT, SAMPLE_DATA, SAMPLE_MODELS, SAMPLE_PARTS


def digest(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array, np.float32).tobytes()).hexdigest()[:16]


def model_digests(model, data: InteractionDataset) -> dict[str, str]:
    out: dict[str, str] = {}
    names = model.class_names
    seeds = [0, 1, 5] if model.settings.seed else [0]
    for i, sid in enumerate(data.sequence_ids):
        leader = data.world(i)[0]
        own = names[int(data.actions[i])]
        out[f"{sid}|{own}"] = digest(model.synthesize(leader, {own: 1.0}))
        if i % 10 == 0:
            other = names[(int(data.actions[i]) + 1) % len(names)]
            out[f"{sid}|mix"] = digest(model.synthesize(leader, {own: 1.0, other: 0.5}, scale=1.2))
            out[f"{sid}|avoid"] = digest(model.synthesize(leader, {other: -1.0}))
            out[f"{sid}|latent"] = digest(model.latent(leader, {own: 1.0}))
            for seed in seeds[1:]:
                out[f"{sid}|{own}|seed{seed}"] = digest(model.synthesize(leader, {own: 1.0}, seed=seed))
    canonical = [data.canonical(i)[0] for i in range(len(data))]
    labels = np.eye(len(names), dtype=np.float32)[data.actions]
    for i, f in enumerate(model.synthesize_batch_canonical(canonical, labels)):
        out[f"batch|{data.sequence_ids[i]}"] = digest(f)
    for path in sorted((REPO_ROOT / "tests" / "fixtures" / "bvh").glob("*.bvh")):
        try:
            leader = read_bvh(path)
        except Exception as err:  # a fixture meant to be refused
            out[f"bvh|{path.name}"] = f"refused: {type(err).__name__}"
            continue
        out[f"bvh|{path.name}"] = digest(model.synthesize(leader, {"shaking_hands": 1.0}))
        if model.part_labels:
            out[f"bvh|{path.name}|parts"] = digest(model.synthesize(leader, {"upper:shaking_hands": 1.0, "lower:pushing": -1.0}))
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--out", type=Path)
    g.add_argument("--compare", type=Path)
    args = p.parse_args()
    data = InteractionDataset.load(SAMPLE_DATA)
    found = {path.name: model_digests(ReactionModel.load(path), data) for path in [*SAMPLE_MODELS.values(), SAMPLE_PARTS]}
    if args.out:
        args.out.write_text(json.dumps(found, indent=0, sort_keys=True))
        print(f"wrote {sum(map(len, found.values()))} digests to {args.out}")
        return 0
    before = json.loads(args.compare.read_text())
    total = differ = 0
    for model, digests in before.items():
        for key, value in digests.items():
            total += 1
            if found.get(model, {}).get(key) != value:
                differ += 1
                if differ <= 10:
                    print(f"differs: {model} {key}")
    print(f"{total - differ} of {total} outputs bit-identical ({differ} differ)")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
