"""Diffusion sampling speed: one 46-frame reaction with 0-3 classes composed (and, for a model with a label per body
part, 1-3 part terms), against the GAN in the same run.

    .venv/bin/python benchmarks/diffusion_speed.py --checkpoint sample_data/imm_diffusion.safetensors [--threads 1]
        [--repeats 30] [--device cpu|cuda] [--gan sample_data/imm_sbu.safetensors] [--spread S] [--memory LEVEL]
        [--sample-steps N]

Prints the median and p90 of `ReactionModel.synthesize_canonical` (clean-up included) for each number of classes
composed (each class is one more network term per sampler step, and so is each pair of classes for a model with pair
terms, such as `imm-diffusion-mixed`'s; a label per body part whose parts differ, with the sampler's join, runs each
part's terms apart, and without it a part network's (part, class) terms), the sampler's steps, and the GAN's median
on the same leader (whole-body labels), interleaved so that both see the same machine load. `--memory` starts the
sampler from the reaction memory (the bundled data's pairs of the model's training subjects), its retrieval included
in the time.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from imm_model.data.dataset import InteractionDataset
from imm_model.data.labels import Label
from imm_model.device import add_device_argument, resolve_device
from imm_model.inference import ReactionModel
from imm_model.paths import SAMPLE_DATA, SAMPLE_GAN


def timed(fn, repeats: int) -> list[float]:
    fn()  # warm-up
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t) * 1000)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--gan", default=str(SAMPLE_GAN))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--spread", type=float, default=None, help="the sampler's spread (default: the model's own)")
    ap.add_argument("--memory", type=float, default=None, help="the sampler's memory_level (default: the model's own)")
    ap.add_argument("--sample-steps", type=int, default=None, help="the sampler's DDIM steps (default: the model's own)")
    add_device_argument(ap, default="cpu")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    threadpool_limits(args.threads)  # numpy's BLAS too: the numpy denoiser's products would otherwise use every core
    device = str(resolve_device(args.device))
    data = InteractionDataset.load(SAMPLE_DATA)
    model, gan = ReactionModel.load(args.checkpoint, device=device), ReactionModel.load(args.gan, device=device)
    if args.spread is not None:
        model.spread = args.spread
    if args.memory is not None:
        model.guidance = replace(model.guidance, memory_level=args.memory)
        model.attach_memory(data)
    if args.sample_steps is not None:
        model.guidance = replace(model.guidance, sample_steps=args.sample_steps)
    leader = data.canonical(int(np.argmax(data.lengths)))[0]
    print(f"checkpoint {args.checkpoint}; {len(leader)} frames; torch and BLAS threads {args.threads}; device {device}; "
          f"{model.guidance.sample_steps} sampler steps; spread {model.spread}; memory {model.guidance.memory_level}; "
          f"pair terms {model.config.pair_terms}; part labels {model.part_labels}")
    names = model.class_names
    cases = [(f"{k} classes composed", {n: 1.0 for n in names[:k]}) for k in range(4)]
    if model.part_labels:
        cases += [(f"parts: {text}", Label.parse(text, names).keys())
                  for text in (f"upper:{names[2]}=1", f"upper:{names[2]}=1,lower:{names[1]}=-1",
                               f"upper:{names[2]}=1,lower:{names[1]}=1", f"upper:{names[2]}=1,lower:{names[1]}=1,{names[3]}=-1")]
    for title, keys in cases:
        label = model.label_vector(keys)
        whole = np.zeros(len(names), np.float32)
        whole[[names.index(k.rpartition(":")[2]) for k, v in keys.items() if v > 0]] = 1.0  # the GAN: the classes asked for
        times, gan_times = [], []
        for _ in range(args.repeats):  # interleaved: both models meet the same load
            times += timed(lambda label=label: model.synthesize_canonical(leader, label), 1)
            gan_times += timed(lambda whole=whole: gan.synthesize_canonical(leader, whole), 1)
        p90 = statistics.quantiles(times, n=10)[-1]
        print(f"{title}: median {statistics.median(times):.1f} ms, p90 {p90:.1f} ms "
              f"(GAN median {statistics.median(gan_times):.1f} ms; ratio {statistics.median(times) / statistics.median(gan_times):.1f}x)")


if __name__ == "__main__":
    main()
