"""`imm train`: train one LOSO fold, all seven, or on all data; optionally export the generator."""

from __future__ import annotations

import argparse
from pathlib import Path

from imm_model.device import add_device_argument


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("train", help="train the reaction model (one LOSO fold, all folds, or all data)")
    from imm_model.families import recipe_names

    p.add_argument("--config", default="imm", help=f"named recipe ({', '.join(recipe_names())}) or a JSON file of overrides")
    p.add_argument("--fold", default="s04", help="held-out subject sXX, 'all' (the 7 LOSO folds) or 'none' (all data)")
    p.add_argument("--out", type=Path, required=True, help="run directory (fold-sXX/ subfolders are created in it)")
    p.add_argument("--data", type=Path, default=None, help="dataset bundle (default: the bundled SBU sample)")
    p.add_argument("--epochs", type=int, default=None, help="override the recipe's number of epochs (the GAN's recipes)")
    p.add_argument("--steps", type=int, default=None, help="override the recipe's number of optimizer steps (the diffusion model's)")
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
    from imm_model.families import load_recipe
    from imm_model.outputs import FolderLock
    from imm_model.paths import SAMPLE_DATA

    for option in ("threads", "epochs", "steps"):
        value = getattr(args, option)
        if value is not None and value < 1:
            raise ValueError(f"--{option} must be >= 1, not {value}")
    if args.resume and args.overwrite:
        raise ValueError("--resume and --overwrite contradict each other: choose one")
    torch.set_num_threads(args.threads)
    device = resolve_device(args.device)
    family, cfg = load_recipe(args.config, seed=args.seed)
    for option in ("epochs", "steps"):  # each family's length is one of these, or it trains no length at all
        if getattr(args, option) is not None:
            if family.length_option != option:
                instead = f": use --{family.length_option}" if family.length_option else ""
                raise ValueError(f"--{option} does not apply to {args.config!r} ({family.title}){instead}")
            _, cfg = load_recipe(args.config, seed=args.seed, **{option: getattr(args, option)})
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
    check_run_dirs(args.out, folds, cfg, args.resume, args.overwrite)
    with contextlib.ExitStack() as locks:  # a trainer already at work in a fold is not cleared or joined
        for subject in folds:
            locks.enter_context(FolderLock(fold_dir(args.out, subject), "--out", "imm train"))
        return _train_folds(args, family, cfg, data, folds, device)


def _train_folds(args: argparse.Namespace, family, cfg, data, folds: list, device) -> int:
    import json

    from imm_model.checkpoint import export_generator, final_checkpoint
    from imm_model.outputs import write_atomic

    if args.overwrite:  # so that no model of the replaced run is shipped, exported or evaluated as this one's
        for subject in folds:
            clear_run(fold_dir(args.out, subject))
    args.out.mkdir(parents=True, exist_ok=True)  # written only once every check has passed
    write_atomic(args.out / "config.json", json.dumps(cfg.to_dict(), indent=1) + "\n")
    for subject in folds:
        out = fold_dir(args.out, subject)
        done = family.train(cfg, data, subject, out, device, resume=args.resume, progress=not args.quiet)
        print(f"fold {subject or 'none'}: {done.line}")
        if args.export:
            export_generator(final_checkpoint(out), args.export)
            print(f"exported generator to {args.export}")
    return 0


RUN_FILES = ("last.safetensors", "best.safetensors", "final.safetensors", "log.csv")
# everything a run writes in its fold directory: what --overwrite removes (nothing else there is touched)
RUN_OWNS = (*RUN_FILES, "last.json", "best.json", "final.json", "curves.png")


def clear_run(fold: Path) -> None:
    for name in RUN_OWNS:
        (fold / name).unlink(missing_ok=True)


def check_run_dirs(out: Path, folds: list, config, resume: bool, overwrite: bool) -> None:
    """Refuse, before anything is written, to replace finished work or to resume what cannot be resumed."""
    import json

    from imm_model.families import same_recipe

    saved = out / "config.json"
    if resume and saved.is_file():
        try:
            before = json.loads(saved.read_text())
        except (OSError, json.JSONDecodeError) as err:
            raise ValueError(f"{saved}: unreadable ({err}); --overwrite starts the runs again") from None
        if not same_recipe(config, before):
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

            _, meta = load_checkpoint(fold / "last.safetensors", framework="np")
            if not same_recipe(config, meta.get("train_config") or {}):
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
