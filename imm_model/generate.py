"""`imm generate`: synthesize reactions from the command line: one leader and one label, or a batch (leader
files or folders, or dataset sequences, times labels or the one-hot grid), one output file per item."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imm_model.data.labels import Label, label_text
from imm_model.device import add_device_argument
from imm_model.errors import DataFormatError, printable
from imm_model.inputs import check_input

LEADER_SUFFIXES = (".bvh", ".npz", ".txt")
LEADER_COPY_SUFFIX = ".leader.bvh"  # the leader written beside each .bvh output


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("generate", help="synthesize the follower's reaction to leader motions")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--leader", type=Path, nargs="+",
                     help="leader files (.bvh, .npz with a 'leader' array, SBU skeleton_pos.txt) or folders of them")
    src.add_argument("--sequence", help="a sequence id of the bundled data, e.g. s01s02/03/001 (its leader is used)")
    src.add_argument("--sequences", help="'all', 'held-out' or comma-separated sequence ids of the bundled data")
    p.add_argument("--label", action="append", default=None,
                   help="e.g. kicking=1,hugging=0.5 or one value per class; the diffusion models (the default) also "
                        "takes upper:CLASS and lower:CLASS (e.g. upper:shaking_hands=1,lower:pushing=-1); repeat it for "
                        "several labels")
    p.add_argument("--grid", action="store_true", help="every one-hot label (one output per leader and class)")
    p.add_argument("--scale", type=float, default=1.0, help="multiplies the label vector (default 1)")
    p.add_argument("--out", type=Path, required=True,
                   help="one item: a .npz or .bvh file (the leader as NAME.leader.bvh beside a .bvh); several: a folder")
    p.add_argument("--format", choices=("npz", "bvh"), default="npz", help="file type of each item in a batch (default npz)")
    p.add_argument("--checkpoint", type=Path, default=None,
                   help="default: the bundled diffusion model; the GAN is sample_data/imm_sbu.safetensors")
    p.add_argument("--data", type=Path, default=None,
                   help="dataset for --sequence(s), and the one a retrieval --checkpoint retrieves from (default: the bundled sample)")
    p.add_argument("--bvh-map", type=Path, default=None, help="JSON {kinect joint: BVH joint name} for a skeleton the name table misses")
    p.add_argument("--raw", action="store_true",
                   help="the network's own follower, without the clean-up (rigid bones, planted feet)")
    p.add_argument("--average-placement", action="store_true",
                   help="place the follower at the mean of where the model places it for the leader and, mirrored back, for "
                        "the leader's mirror image (its motion unchanged; docs/experiments/mirror-placement.md)")
    p.add_argument("--seed", type=int, default=0,
                   help="sampler seed of a stochastic model (the diffusion model): another seed, another reaction (default 0)")
    p.add_argument("--samples", type=int, default=1,
                   help="reactions per leader and label, drawn with seeds --seed, --seed + 1, ... (a stochastic model; "
                        "more than 1 writes a folder, each file named with its seed)")
    p.add_argument("--spread", type=float, default=None,
                   help="how loosely a diffusion model trained with noised leaders follows the leader, 0..1: higher "
                        "draws wider variations (default: the model's own)")
    p.add_argument("--memory", type=float, default=None, metavar="LEVEL",
                   help="start a diffusion model's sampler from a real reaction to a similar leader (the reaction memory: "
                        "the pairs of --data, or of the bundled data, that the model was trained on), noised to LEVEL 0..1; "
                        "lower keeps more of the real reaction (default: the model's own, 1 = from pure noise)")
    p.add_argument("--force", action="store_true", help="replace outputs that exist")
    add_device_argument(p)
    p.set_defaults(func=_cmd_generate)


def leader_files(paths: list[Path]) -> list[Path]:
    """Files as given, folders expanded to their leader files (sorted, without the leader copies this command wrote
    there); a missing path, one that is not a regular file (a FIFO, a device), or nothing found is an error."""
    files = []
    for path in paths:
        if path.is_dir():
            files += sorted(f for f in path.iterdir() if f.suffix.lower() in LEADER_SUFFIXES and not _is_leader_copy(f))
        else:
            check_input(path, "leader file")
            files.append(path)
    if not files:
        raise DataFormatError(f"no leader files ({', '.join(LEADER_SUFFIXES)}) in {', '.join(map(str, paths))}")
    return files


def label_vectors(args: argparse.Namespace, model) -> list[np.ndarray]:
    """The labels asked for, each parsed and checked once."""
    if args.grid:
        if args.label:
            raise ValueError("--grid makes its own labels (one per class): give --label or --grid, not both")
        # through label_vector, so the scale meets the same finite and range checks as a given label
        return [model.label_vector({name: 1.0}, args.scale) for name in model.class_names]
    if not args.label:
        raise ValueError("give --label (repeat it for several) or --grid")
    return [model.label_vector(Label.parse(text, model.class_names), args.scale) for text in args.label]


def label_slug(vec: np.ndarray, class_names) -> str:
    return "_".join(f"{k.replace(':', '-')}{v:+g}" for k, v in Label.of(vec, class_names).keys().items()) or "neutral"


def _leaders(args: argparse.Namespace) -> list[tuple[str, np.ndarray, str]]:
    """-> (item name, world leader (T, J, 3), where it came from: a leader file or a dataset sequence id) per leader."""
    from imm_model.data.leader_file import read_leader_file

    if args.leader:
        return [(f.stem, read_leader_file(f, args.bvh_map), str(f)) for f in leader_files(args.leader)]
    from imm_model.data.dataset import InteractionDataset
    from imm_model.paths import SAMPLE_DATA

    data = InteractionDataset.load(args.data or SAMPLE_DATA)
    if args.sequence:
        ids = [args.sequence]
    elif args.sequences == "all":
        ids = list(data.sequence_ids)
    elif args.sequences == "held-out":
        ids = [s for i, s in enumerate(data.sequence_ids) if data.held_out[i]]
    else:
        ids = [s.strip() for s in args.sequences.split(",") if s.strip()]
    return [(sid.replace("/", "-"), data.world(data.index_of(sid))[0], sid) for sid in ids]


def leader_copy(path: Path) -> Path:
    """The leader written beside a .bvh output (a BVH holds one character)."""
    return path.with_suffix(LEADER_COPY_SUFFIX)


def _is_leader_copy(path: Path) -> bool:
    """NAME.leader.bvh beside NAME.bvh: a leader copy this command wrote, not a leader of its own (a take named
    NAME.leader.bvh alone is one)."""
    name = path.name
    return name.lower().endswith(LEADER_COPY_SUFFIX) and path.with_name(name[:-len(LEADER_COPY_SUFFIX)] + ".bvh").is_file()


def _inputs(args: argparse.Namespace, model) -> list[Path]:
    """Every file the command reads: never one of its outputs, even with --force."""
    from imm_model.checkpoint import sidecar_path
    from imm_model.paths import SAMPLE_DATA

    data = [args.data or SAMPLE_DATA] if not args.leader or args.memory is not None else []  # --memory reads it too
    files = [*(leader_files(args.leader) if args.leader else []), *data]
    checkpoint = [model.path, sidecar_path(model.path)] if model.path else []
    return [*files, *checkpoint, *([args.bvh_map] if args.bvh_map else [])]


def _cmd_generate(args: argparse.Namespace) -> int:
    import torch

    from imm_model.device import resolve_device
    from imm_model.errors import DataFormatError, LabelError
    from imm_model.inference import ReactionModel, check_seeds
    from imm_model.outputs import Output, plan_outputs
    from imm_model.paths import SAMPLE_DATA

    seeds = check_seeds(args.seed, args.samples)
    if args.leader:  # a missing leader is named before any check of what --out can hold
        leader_files(args.leader)
    one_leader = bool(args.sequence) or bool(args.leader and len(args.leader) == 1 and args.leader[0].is_file())
    single = one_leader and not args.grid and len(args.label or []) <= 1 and len(seeds) == 1
    if not single and args.out.suffix.lower() in (".npz", ".bvh"):
        raise ValueError(f"--out {args.out}: several items need a folder, not a file name")
    torch.set_num_threads(2)
    model = ReactionModel.load(args.checkpoint, resolve_device(args.device), data=args.data)
    model.raw, model.average_placement = args.raw, args.average_placement
    name = model.path.name if model.path else "this model"
    if len(seeds) > 1 and not model.settings.seed:
        raise ValueError(f"--samples {args.samples}: {name} ({model.title}) is deterministic: every seed gives the same "
                         "reaction")
    if args.spread is not None:
        if not model.settings.spread:
            raise ValueError(f"--spread: {name} ({model.title}) has no spread setting (it needs a diffusion model trained "
                             "with noised leaders)")
        model.spread = args.spread
    if args.memory is not None:
        from imm_model.data.dataset import InteractionDataset

        try:
            model.use_memory(args.memory, InteractionDataset.load(args.data or SAMPLE_DATA))
        except LabelError as err:
            raise ValueError(f"--memory: {name}: {err}") from None
    labels = label_vectors(args, model)
    leaders = []
    for item, leader, source in _leaders(args):  # each checked and framed once, before anything is written
        try:
            leaders.append((item, model.prepare_leader(leader), source))
        except DataFormatError as err:
            raise DataFormatError(f"{source}: {err}") from None
    if single:
        paths = {(0, 0, seeds[0]): args.out}
        outputs = [Output(args.out)]
    else:
        tag = (lambda seed: f"_seed{seed}") if len(seeds) > 1 else (lambda seed: "")  # noqa: E731
        paths = {(k, c, seed): args.out / f"{name}_{label_slug(vec, model.class_names)}{tag(seed)}.{args.format}"
                 for k, (name, _, _) in enumerate(leaders) for c, vec in enumerate(labels) for seed in seeds}
        outputs = [Output(path, "--out", leaders[k][2]) for (k, _, _), path in paths.items()]
    outputs += [Output(leader_copy(out.path), "--out's leader copy", out.source)
                for out in list(outputs) if out.path.suffix.lower() == ".bvh"]
    plan_outputs(outputs, _inputs(args, model), args.force)  # all refused before anything is written
    if single:
        return _generate_one(args, model, leaders[0], labels[0], seeds[0])
    return _generate_batch(args, model, leaders, labels, seeds, paths, len(outputs))


def _generate_one(args: argparse.Namespace, model, leader_item, vec: np.ndarray, seed: int) -> int:
    _, leader, source = leader_item
    follower = _synthesize(model, [leader], vec, seed)[0]
    _write(args.out, leader, follower, model, vec, args.scale, None if args.leader else source, seed, args.force)
    desc = label_text(vec, model.class_names) or "all zero"
    beside = f" (the leader in {leader_copy(args.out)})" if args.out.suffix.lower() == ".bvh" else ""
    print(printable(f"wrote {args.out}{beside}: follower {follower.shape[0]} frames x {follower.shape[1]} joints (label {desc})"))
    return 0


def _generate_batch(args: argparse.Namespace, model, leaders: list, labels: list[np.ndarray], seeds: list[int], paths: dict,
                    num_files: int) -> int:
    """Every leader x every label x every seed, one file each in the --out folder (with its leader copy for .bvh); all
    leaders in one batch per label and seed."""
    from tqdm import tqdm

    with tqdm(total=len(paths), desc="generate", unit="item") as bar:
        for c, vec in enumerate(labels):
            for seed in seeds:
                followers = _synthesize(model, [leader for _, leader, _ in leaders], vec, seed)
                for k, ((_, leader, source), follower) in enumerate(zip(leaders, followers, strict=True)):
                    _write(paths[k, c, seed], leader, follower, model, vec, args.scale, None if args.leader else source, seed,
                           args.force)
                    bar.update()
    beside = ", each with its leader copy" if args.format == "bvh" else ""
    samples = f" x {len(seeds)} seeds" if len(seeds) > 1 else ""
    print(printable(f"wrote {num_files} files ({len(leaders)} leaders x {len(labels)} labels{samples}{beside}) to {args.out}"))
    return 0


def _synthesize(model, leaders: list, vec: np.ndarray, seed: int = 0) -> list[np.ndarray]:
    """Prepared leaders -> world followers, in one batch (each leader in its own canonical frame)."""
    from imm_model.outputs import check_finite

    return [check_finite(f, "the synthesized follower (leader coordinates out of range?)")
            for f in model.synthesize_leaders(leaders, vec, [seed] * len(leaders))]


def _write(path: Path, leader, follower: np.ndarray, model, vec: np.ndarray, scale: float, sid: str | None,
           seed: int, replace: bool) -> None:
    """One item: a .bvh (with the leader's copy beside it) or an .npz of the whole interaction; `leader` prepared.
    Without `replace` an existing file is refused even if another command wrote it after `plan_outputs` checked (two
    runs at one --out: one of them fails)."""
    from imm_model.outputs import write_atomic, write_files

    if path.suffix.lower() == ".bvh":
        from imm_model.data.bvh import write_bvh

        write_files([(path, lambda tmp: write_bvh(tmp, follower, model.skeleton)),
                     (leader_copy(path), lambda tmp: write_bvh(tmp, leader.world, model.skeleton))], replace)
        return
    from imm_model.interaction_file import interaction_arrays, interaction_bytes

    write_atomic(path, interaction_bytes(interaction_arrays(
        leader.world, follower, leader.frame, model.skeleton, class_names=model.class_names, label=vec, scale=scale,
        checkpoint=model.path.name if model.path else "", fps=15.0, sequence_id=sid, **model.provenance(seed))), replace)
