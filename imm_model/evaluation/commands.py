"""`imm evaluate`: a checkpoint (one fold) or runs (all their folds, several seeds) against every baseline.

Prints the headline, the AFD table and each fold group's AFD, FID, KID, precision/recall and jitter with 95 %
intervals (evaluation/intervals.py); writes the whole summary as JSON, Markdown and PNG figures.
docs/evaluation-protocol.md defines every number.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate", help="AFD, FID, KID, precision/recall, recognition, label control and plausibility of a model vs strong "
                         "baselines on LOSO folds, with 95 percent intervals",
        description="With --checkpoint and no --fold: the subject the checkpoint held out. With --run DIR [DIR ...] (one per "
                    "seed): every DIR/fold-sXX/final.safetensors (a refit) or else best.safetensors on its own held-out subject "
                    "(--fold all, the default for --run) or one fold. Classifiers and the label-free baseline are trained on "
                    "each fold's training subjects once and cached ($IMM_CACHE_DIR, default ~/.cache/imm-studio).")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--checkpoint", type=Path, default=None,
                     help="a checkpoint (default: the bundled GAN, imm_sbu.safetensors); may contain {subject}, e.g. "
                          "runs/loso/fold-{subject}/best.safetensors")
    src.add_argument("--run", type=Path, nargs="+", default=None, help="run directories made by `imm train --fold all` (one per seed)")
    p.add_argument("--fold", default=None, help="sXX or 'all' (default: the checkpoint's held-out subject; all for --run)")
    p.add_argument("--data", type=Path, default=None, help="dataset bundle (default: the bundled SBU sample)")
    p.add_argument("--baselines", default="nn1,knn_dtw,template,men", help="comma-separated subset of nn1,knn_dtw,template,men")
    p.add_argument("--men-run", type=Path, default=None,
                   help="a run of `imm train --config men --fold all` to use as the label-free baseline (default: train and cache it)")
    p.add_argument("--men-config", default="men",
                   help="the recipe the label-free baseline is trained and cached with when no --men-run is given: a name "
                        "or a JSON file of overrides on one (default: men)")
    p.add_argument("--classifier-config", type=Path, default=None,
                   help="JSON of ClassifierConfig overrides applied to every classifier (e.g. {\"epochs\": 30})")
    p.add_argument("--json", type=Path, default=None, help="write the whole summary as JSON")
    p.add_argument("--markdown", type=Path, default=None, help="write every table as Markdown")
    p.add_argument("--figures", type=Path, default=None, help="write PNG figures into this folder")
    p.add_argument("--raw", action="store_true",
                   help="score the networks' own followers, without the clean-up (rigid bones, planted feet)")
    p.add_argument("--average-placement", action="store_true",
                   help="place each model follower at the mean of where the model places it for the leader and, mirrored "
                        "back, for the leader's mirror image (its motion unchanged)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--force", action="store_true", help="replace existing --json/--markdown files")
    p.set_defaults(func=_cmd_evaluate)


def _options(args: argparse.Namespace):
    from imm_model.checkpoint import final_checkpoint
    from imm_model.evaluation.loso import EvalOptions
    from imm_model.families import load_recipe
    from imm_model.inputs import MAX_SETTINGS_BYTES, read_input_text
    from imm_model.model.classifier_config import FOLLOWER, FOLLOWER_JUDGE, INTERACTION, LOWER_JUDGE, UPPER_JUDGE, ClassifierConfig

    overrides = {}
    if args.classifier_config is not None:
        text = read_input_text(args.classifier_config, "classifier config", MAX_SETTINGS_BYTES)
        try:
            overrides = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as err:
            raise ValueError(f"{args.classifier_config}: unreadable classifier config ({type(err).__name__})") from None
        if not isinstance(overrides, dict):
            raise ValueError(f"{args.classifier_config}: a classifier config is a JSON object")
    configs = {}
    for name, base in (("interaction", INTERACTION), ("follower", FOLLOWER), ("judge", FOLLOWER_JUDGE), ("upper", UPPER_JUDGE),
                       ("lower", LOWER_JUDGE)):
        configs[name] = ClassifierConfig.from_dict(base.to_dict() | overrides)
    if args.men_run is not None and not args.men_run.is_dir():
        raise ValueError(f"--men-run {args.men_run}: run directory not found")
    men = (lambda s: final_checkpoint(args.men_run / f"fold-{s}")) if args.men_run else None
    baselines = tuple(b.strip() for b in args.baselines.split(",") if b.strip())
    if not baselines:
        raise ValueError("--baselines: name at least one of nn1, knn_dtw, template, men")
    if args.men_run is None and "men" in baselines:
        load_recipe(args.men_config)  # an unknown recipe or a bad file is refused before hours of evaluation
    return EvalOptions(baselines=baselines, men_checkpoint=men, men_config=args.men_config, progress=not args.quiet, raw=args.raw,
                       average_placement=args.average_placement, **configs)


def _jobs(args: argparse.Namespace, subjects: list[str]) -> list[tuple[Path, str]]:
    """(checkpoint, subject) pairs to evaluate."""
    from imm_model.checkpoint import final_checkpoint
    from imm_model.data.splits import normalize_fold
    from imm_model.inference import ReactionModel

    fold = normalize_fold(args.fold) or ("all" if args.run is not None else None)
    if fold not in (None, "all") and fold not in subjects:
        raise ValueError(f"--fold {fold!r}: expected one of {subjects} or 'all'")
    folds = subjects if fold == "all" else [fold]
    if args.run is not None:
        return [(final_checkpoint(run / f"fold-{s}"), s) for run in args.run for s in folds]
    templated = "{subject}" in str(args.checkpoint)
    if fold == "all" and not templated:
        raise ValueError("--fold all needs per-fold checkpoints: --run DIR or --checkpoint with {subject} in the path")
    if fold is None:
        if templated:
            raise ValueError("give --fold sXX or --fold all with a per-fold checkpoint pattern")
        held = ReactionModel.load(args.checkpoint).held_out_subject
        if held is None:
            raise ValueError(f"{args.checkpoint}: held out no subject; give --fold sXX")
        folds = [held]
    return [(Path(str(args.checkpoint).replace("{subject}", s)), s) for s in folds]


def _cmd_evaluate(args: argparse.Namespace) -> int:
    import torch

    from imm_model.cache import cache_dir
    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import all_subjects
    from imm_model.evaluation.loso import evaluate_fold
    from imm_model.evaluation.report import summarize
    from imm_model.evaluation.tables import headline, metric_table, printed_distribution
    from imm_model.inference import ReactionModel
    from imm_model.outputs import check_finite
    from imm_model.paths import SAMPLE_DATA, SAMPLE_GAN

    torch.set_num_threads(2)
    cache_dir()  # an unusable cache folder is refused before any classifier or baseline is trained for it
    data = InteractionDataset.load(args.data or SAMPLE_DATA)
    if args.run is None and args.checkpoint is None:
        args.checkpoint = SAMPLE_GAN
    opts = _options(args)
    jobs = _jobs(args, all_subjects(data.subject_pairs))
    _plan_outputs(args, jobs)  # refused before hours of evaluation, not after
    results, latent = [], None
    for k, (path, subject) in enumerate(jobs, start=1):
        t0 = time.perf_counter()
        model = ReactionModel.load(path, data=args.data)
        if model.held_out_subject != subject:
            print(f"warning: {path} held out {model.held_out_subject}, not {subject}: its training set contains the test "
                  f"subject, so these numbers are optimistic", file=sys.stderr)
        first = latent is None  # the t-SNE figure shows the first fold's models only
        embeddings = {} if first else None
        result = evaluate_fold(model, data, subject, opts, embeddings) | {"seed": model.info.get("training", {}).get("seed")}
        if first:
            latent = {"subject": subject, "latents": embeddings}
        results.append(result)
        print(f"[{k}/{len(jobs)}] fold {subject} ({result['group']}), {path}: model AFD "
              f"{sum(v['afd'] for v in result['model']['classes'].values()) / len(result['model']['classes']):.3f} "
              f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    summary = summarize(results, data.class_names)
    summary["followers"] = {"clean_up": not opts.raw, "average_placement": opts.average_placement}  # how they were made
    check_finite(summary["mean"]["afd"], "the model's mean AFD (a checkpoint with NaN weights?)")
    print(headline(summary))
    print(metric_table(summary, "afd"))
    print(printed_distribution(summary))
    _write_outputs(args, summary, latent, data)
    return 0


def _plan_outputs(args: argparse.Namespace, jobs: list[tuple[Path, str]]) -> None:
    from imm_model.checkpoint import sidecar_path
    from imm_model.outputs import Output, plan_outputs
    from imm_model.paths import SAMPLE_DATA

    outputs = [Output(getattr(args, option), f"--{option}") for option in ("json", "markdown") if getattr(args, option)]
    checkpoints = [f for path, _ in jobs for f in (path, sidecar_path(path))]
    plan_outputs(outputs, [args.data or SAMPLE_DATA, args.classifier_config, *checkpoints], args.force)
    if args.figures:  # a folder whose figures each evaluation replaces: it only has to be one, and writable
        plan_outputs([Output(args.figures / "figure.png", "--figures")], force=True)


def _write_outputs(args: argparse.Namespace, summary: dict, latent: dict | None, data) -> None:
    from imm_model.evaluation.figures import write_figures
    from imm_model.evaluation.tables import markdown_report
    from imm_model.outputs import write_files

    reports = [(args.json, json.dumps(summary, indent=1, allow_nan=True) + "\n")] if args.json else []
    reports += [(args.markdown, markdown_report(summary) + "\n")] if args.markdown else []
    write_files(reports)
    if args.figures:
        paths = write_figures(summary, latent, data.actions, args.figures, progress=lambda m: print(m, file=sys.stderr))
        print(f"figures: {', '.join(str(p) for p in paths)}", file=sys.stderr)
