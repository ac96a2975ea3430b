"""`imm train`: train one LOSO fold, all seven, or on all data; optionally export the generator."""

from __future__ import annotations

import argparse
from pathlib import Path

from imm_model.device import add_device_argument


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("train", help="train the reaction model (one LOSO fold, all folds, or all data)")
    p.add_argument("--config", default="imm",
                   help="named recipe (imm, imm-steer, imm-move, imm-control, imm-critic, men, paper, imm-diffusion, imm-diffusion-mixed) "
                        "or a JSON file of overrides")
    p.add_argument("--fold", default="s04", help="held-out subject sXX, 'all' (the 7 LOSO folds) or 'none' (all data)")
    p.add_argument("--out", type=Path, required=True, help="run directory (fold-sXX/ subfolders are created in it)")
    p.add_argument("--data", type=Path, default=None, help="dataset bundle (default: the bundled SBU sample)")
    p.add_argument("--epochs", type=int, default=None, help="override the recipe's number of epochs (GAN recipes)")
    p.add_argument("--steps", type=int, default=None, help="override the recipe's number of optimizer steps (diffusion recipes)")
    p.add_argument("--seed", type=int, default=None, help="override the recipe's seed")
    p.add_argument("--resume", action="store_true", help="continue from each fold's last.safetensors")
    p.add_argument("--overwrite", action="store_true", help="replace the runs already in --out (default: refuse)")
    p.add_argument("--export", type=Path, default=None, help="copy the (single fold's) best generator to this .safetensors")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_device_argument(p)
    p.set_defaults(func=_cmd_train)


def fold_dir(out: Path, subject: str | None) -> Path:
    return out / (f"fold-{subject}" if subject else "fold-none")


def _cmd_train(args: argparse.Namespace) -> int:
    import contextlib

    import torch

    from imm_model.data.dataset import InteractionDataset
    from imm_model.data.splits import all_subjects, normalize_fold
    from imm_model.device import resolve_device
    from imm_model.outputs import FolderLock
    from imm_model.paths import SAMPLE_DATA
    from imm_model.training.config import load_config
    from imm_model.training.diffusion import diffusion_recipe
    from imm_model.training.diffusion import load_config as load_diffusion_config

    if args.threads < 1:
        raise ValueError(f"--threads must be >= 1, not {args.threads}")
    if args.epochs is not None and args.epochs < 1:
        raise ValueError(f"--epochs must be >= 1, not {args.epochs}")
    if args.resume and args.overwrite:
        raise ValueError("--resume and --overwrite contradict each other: choose one")
    torch.set_num_threads(args.threads)
    device = resolve_device(args.device)
    diffusion = diffusion_recipe(args.config)
    if (args.steps if not diffusion else args.epochs) is not None:
        raise ValueError(f"--{'epochs' if diffusion else 'steps'} does not apply to {args.config!r}: "
                         f"use --{'steps' if diffusion else 'epochs'}")
    if args.steps is not None and args.steps < 1:
        raise ValueError(f"--steps must be >= 1, not {args.steps}")
    if diffusion:
        cfg = load_diffusion_config(args.config, steps=args.steps, seed=args.seed)
    else:
        cfg = load_config(args.config, epochs=args.epochs, seed=args.seed)
    data = InteractionDataset.load(args.data or SAMPLE_DATA)
    subjects = all_subjects(data.subject_pairs)
    args.fold = normalize_fold(args.fold)
    if args.fold == "all":
        folds: list[str | None] = list(subjects)
    elif args.fold == "none":
        folds = [None]
    elif args.fold in subjects:
        folds = [args.fold]
    else:
        raise ValueError(f"--fold {args.fold!r}: expected one of {subjects}, 'all' or 'none'")
    if args.export:
        config_file = [Path(args.config)] if Path(args.config).is_file() else []
        reads = [args.data or SAMPLE_DATA, *config_file, *(fold_dir(args.out, s) / f for s in folds for f in RUN_OWNS)]
        check_export_path(args.export, len(folds), args.overwrite, reads)
    check_run_dirs(args.out, folds, cfg.to_dict(), args.resume, args.overwrite)
    with contextlib.ExitStack() as locks:  # a trainer already at work in a fold is not cleared or joined
        for subject in folds:
            locks.enter_context(FolderLock(fold_dir(args.out, subject), "--out", "imm train"))
        return _train_folds(args, cfg, data, folds, diffusion, device)


def _train_folds(args: argparse.Namespace, cfg, data, folds: list, diffusion: bool, device) -> int:
    import json

    from imm_model.checkpoint import export_generator, final_checkpoint
    from imm_model.outputs import write_atomic
    from imm_model.training.diffusion import DiffusionTrainer
    from imm_model.training.refit import refit
    from imm_model.training.trainer import Trainer

    if args.overwrite:  # so that no model of the replaced run is shipped, exported or evaluated as this one's
        for subject in folds:
            clear_run(fold_dir(args.out, subject))
    args.out.mkdir(parents=True, exist_ok=True)  # written only once every check has passed
    write_atomic(args.out / "config.json", json.dumps(cfg.to_dict(), indent=1) + "\n")
    for subject in folds:
        trainer = (DiffusionTrainer if diffusion else Trainer)(cfg, data, subject, fold_dir(args.out, subject), device)
        if args.resume and (trainer.out / "last.safetensors").exists():
            trainer.resume()
        if diffusion:
            print(f"fold {subject or 'none'}: {cfg.steps} steps -> {trainer.fit(progress=not args.quiet)}")
        else:
            state = trainer.fit(progress=not args.quiet)
            print(f"fold {subject or 'none'}: best validation AFD {state.best_val:.4f} m at epoch {state.best_epoch} "
                  f"({state.epoch} epochs) -> {trainer.out / 'best.safetensors'}")
        if not diffusion and cfg.refit:
            path = refit(trainer, progress=not args.quiet)
            print(f"fold {subject or 'none'}: refit on training + validation for {state.best_epoch + 1} epochs -> {path}")
        if args.export:
            export_generator(final_checkpoint(trainer.out), args.export)
            print(f"exported generator to {args.export}")
    return 0


RUN_FILES = ("last.safetensors", "best.safetensors", "final.safetensors", "log.csv")
# everything a run writes in its fold directory: what --overwrite removes (nothing else there is touched)
RUN_OWNS = (*RUN_FILES, "last.json", "best.json", "final.json", "curves.png")


def clear_run(fold: Path) -> None:
    for name in RUN_OWNS:
        (fold / name).unlink(missing_ok=True)


def check_run_dirs(out: Path, folds: list, config: dict, resume: bool, overwrite: bool) -> None:
    """Refuse, before anything is written, to replace finished work or to resume what cannot be resumed."""
    import json

    saved = out / "config.json"
    if resume and saved.is_file():
        try:
            before = json.loads(saved.read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise ValueError(f"{saved}: unreadable ({err}); --overwrite starts the runs again") from None
        from imm_model.training.config import same_recipe

        if not same_recipe(before, config):
            raise ValueError(f"--resume: {out} was trained with a different config; resume with the same --config/--seed")
    for subject in folds:
        fold = fold_dir(out, subject)
        present = [f for f in RUN_FILES if (fold / f).exists()]
        if present and not (resume or overwrite):
            raise ValueError(f"{fold} already holds a run ({', '.join(present)}): --resume continues it, --overwrite replaces it")
        if resume and present and "last.safetensors" not in present:
            raise ValueError(f"--resume: {fold} has no last.safetensors to continue from; --overwrite starts it again")
        if resume and "last.safetensors" in present:  # a mismatched pair or recipe, before config.json is rewritten
            from imm_model.checkpoint import load_checkpoint
            from imm_model.training.config import same_recipe

            _, meta = load_checkpoint(fold / "last.safetensors", framework="np")
            if not same_recipe(meta.get("train_config") or {}, config):
                raise ValueError(f"{fold / 'last.safetensors'}: saved with a different training config; resume with "
                                 f"the same --config/--seed")


def check_export_path(path: Path, num_folds: int, overwrite: bool, inputs: list[Path]) -> None:
    """An --export destination that would fail or destroy something (an existing file without --overwrite, the
    run's own checkpoints, the data) is refused before training starts."""
    import os

    from imm_model.checkpoint import sidecar_path
    from imm_model.outputs import Output, plan_outputs

    if num_folds != 1:
        raise ValueError("--export needs a single fold")
    if path.suffix != ".safetensors":
        raise ValueError(f"--export {path}: expected a .safetensors file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir() or not os.access(parent, os.W_OK):
        raise ValueError(f"--export {path}: {parent} is not a writable directory")
    plan_outputs([Output(path, "--export"), Output(sidecar_path(path), "--export's sidecar")], inputs, overwrite,
                 force_option="--overwrite")
