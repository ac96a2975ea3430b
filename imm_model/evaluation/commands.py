"""`imm evaluate`: per-class AFD of a checkpoint (or a run's per-fold checkpoints) vs nearest neighbour."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate", help="per-class AFD of the model and the nearest-neighbour baseline on LOSO folds",
        description="With --checkpoint and no --fold: the subject the checkpoint held out. With --run DIR: "
                    "every DIR/fold-sXX/final.safetensors (a refit) or else best.safetensors on its own held-out subject "
                    "(--fold all, the default for --run) or one fold.")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--checkpoint", type=Path, default=None,
                     help="a checkpoint (default: the bundled one); may contain {subject}, e.g. runs/loso/fold-{subject}/best.safetensors")
    src.add_argument("--run", type=Path, default=None, help="a run directory made by `imm train --fold all`")
    p.add_argument("--fold", default=None, help="sXX or 'all' (default: the checkpoint's held-out subject; all for --run)")
    p.add_argument("--data", type=Path, default=None, help="dataset bundle (default: the bundled SBU sample)")
    p.add_argument("--json", type=Path, default=None, help="write the results as JSON")
    p.add_argument("--markdown", type=Path, default=None, help="write the table as Markdown")
    p.set_defaults(func=_cmd_evaluate)


def normalize_fold(fold: str | None) -> str | None:
    """'s04', 'loso-s04', '4' -> 's04'; 'all' and None unchanged."""
    if fold is None or fold == "all":
        return fold
    fold = fold.removeprefix("loso-")
    if fold.isdigit():
        fold = f"s{int(fold):02d}"
    return fold


def _checkpoint_for(args: argparse.Namespace, subject: str) -> Path:
    from imm_model.checkpoint import final_checkpoint

    if args.run is not None:
        return final_checkpoint(args.run / f"fold-{subject}")
    return Path(str(args.checkpoint).format(subject=subject))


def _cmd_evaluate(args: argparse.Namespace) -> int:
    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import all_subjects
    from imm_model.evaluation.loso import evaluate_fold, markdown_table, summarize
    from imm_model.inference import ReactionModel
    from imm_model.paths import SAMPLE_CHECKPOINT, SAMPLE_DATA

    torch.set_num_threads(2)
    data = InteractionDataset.load(args.data or SAMPLE_DATA)
    subjects = all_subjects(data.subject_pairs)
    if args.run is None and args.checkpoint is None:
        args.checkpoint = SAMPLE_CHECKPOINT
    templated = args.run is not None or "{subject}" in str(args.checkpoint)
    fold = normalize_fold(args.fold) or ("all" if args.run is not None else None)
    if fold == "all":
        if not templated:
            raise ValueError("--fold all needs per-fold checkpoints: --run DIR or --checkpoint with {subject} in the path")
        folds = subjects
    elif fold is None:
        if templated:
            raise ValueError("give --fold sXX or --fold all with a per-fold checkpoint pattern")
        held = ReactionModel.load(args.checkpoint).held_out_subject
        if held is None:
            raise ValueError(f"{args.checkpoint}: held out no subject; give --fold sXX")
        folds = [held]
    elif fold in subjects:
        folds = [fold]
    else:
        raise ValueError(f"--fold {fold!r}: expected one of {subjects} or 'all'")
    results = []
    for s in folds:
        model = ReactionModel.load(_checkpoint_for(args, s) if templated else args.checkpoint)
        if model.held_out_subject != s:
            print(f"warning: {model.path} held out {model.held_out_subject}, not {s}: its training set contains the test "
                  f"subject, so these numbers are optimistic", file=sys.stderr)
        results.append(evaluate_fold(model, data, s))
    summary = summarize(results, data.class_names)
    table = markdown_table(summary)
    print(f"LOSO folds: {', '.join(summary['folds'])} (AFD in SBU normalized units)")
    print(table)
    print(f"mean ratio {summary['mean_ratio']:.3f}, worst class ratio {summary['max_ratio']:.3f}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(summary, indent=1) + "\n")
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(table + "\n")
    return 0
