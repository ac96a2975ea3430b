"""The `imm` command line. Each subcommand lives next to the code it drives; this file wires them.

Errors the user can fix (bad files, labels, checkpoints, paths) are printed as one line and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points
from pathlib import Path

from imm_model.errors import IMMError, printable

# Modules that contribute subcommands: each has `register(subparsers)`. They keep heavy imports
# (torch, VTK, trame) inside their command functions so `imm --help` and `imm data` stay fast.
COMMAND_MODULES: dict[str, str] = {
    "data": "imm_model.cli",
    "train": "imm_model.train",
    "evaluate": "imm_model.evaluation.commands",
    "generate": "imm_model.generate",
    "reproduce": "imm_model.reproduce.commands",
}
# Front ends built on the library (the studio) add commands through this entry-point group, so the
# library never imports them by name.
PLUGIN_GROUP = "imm.commands"


def register(subparsers: argparse._SubParsersAction) -> None:
    """The `imm data ...` commands."""
    data = subparsers.add_parser("data", help="inspect datasets and rebuild the bundled sample file")
    sub = data.add_subparsers(dest="data_command", required=True)
    summary = sub.add_parser("summary", help="per-class counts, lengths and subjects")
    summary.add_argument(
        "--data", type=Path, default=None,
        help="a bundle .npz, a raw SBU folder or a K3HI folder (default: the bundled sample file)",
    )
    summary.set_defaults(func=_cmd_summary)
    build = sub.add_parser("build-sample", help="rebuild sample_data/sbu_interactions.npz from the raw SBU files")
    build.add_argument("--raw", type=Path, default=None, help="raw SBU folder (default: ../shared/datasets/sbu_kinect_interaction)")
    build.add_argument("--out", type=Path, default=None, help="output .npz (default: sample_data/sbu_interactions.npz)")
    build.add_argument("--force", action="store_true", help="replace --out if it exists")
    build.set_defaults(func=_cmd_build_sample)
    judge = sub.add_parser("build-judge", help="train one of the studio's 'reads as' classifiers (follower-only, real data only)")
    judge.add_argument("--inputs", choices=("follower", "upper", "lower"), default="follower",
                       help="what it reads: the whole follower, or its upper or lower body (the part judges; default follower)")
    judge.add_argument("--fold", default="s04", help="held-out subject, as the bundled model's (default s04)")
    judge.add_argument("--data", type=Path, default=None, help="dataset bundle (default: the bundled SBU sample)")
    judge.add_argument("--out", type=Path, default=None,
                       help="output .safetensors (default: the bundled follower_judge, upper_judge or lower_judge"
                            ".safetensors, by --inputs)")
    judge.add_argument("--force", action="store_true", help="replace --out and its .json sidecar if they exist")
    judge.set_defaults(func=_cmd_build_judge)


def _cmd_summary(args: argparse.Namespace) -> int:
    from imm_model.data.bundle import load_any, summary_table
    from imm_model.data.dataset import InteractionDataset
    from imm_model.errors import DataFormatError
    from imm_model.paths import SAMPLE_DATA

    path = args.data or SAMPLE_DATA
    source = load_any(path)
    if not len(source):  # a raw folder whose every file was skipped: the first reason is the one line
        raise DataFormatError(source.skipped[0][1] if source.skipped else f"{path}: no sequences found")
    kind = "bundle" if isinstance(source, InteractionDataset) else "raw"
    print(f"{path} ({kind}, {len(source)} sequences)")
    print(summary_table(source))
    if not isinstance(source, InteractionDataset) and source.skipped:
        print(source.report(), file=sys.stderr)
    return 0


def _cmd_build_sample(args: argparse.Namespace) -> int:
    from imm_model.data.bundle import build_sbu_bundle
    from imm_model.outputs import Output, plan_outputs
    from imm_model.paths import SAMPLE_DATA, sbu_raw_root

    raw = args.raw or sbu_raw_root()
    out = args.out or SAMPLE_DATA
    plan_outputs([Output(out)], force=args.force)  # refused before the build, and again at the write (write_files)
    data = build_sbu_bundle(raw)
    data.save(out, replace=args.force)
    print(f"wrote {out}: {len(data)} sequences, {int(data.lengths.sum())} frames, {out.stat().st_size / 1e6:.2f} MB")
    return 0


def _cmd_build_judge(args: argparse.Namespace) -> int:
    from imm_model.cache import fold_classifier
    from imm_model.checkpoint import save_checkpoint, sidecar_path
    from imm_model.data.dataset import InteractionDataset
    from imm_model.errors import DataFormatError
    from imm_model.model.classifier_config import FOLLOWER_JUDGE, LOWER_JUDGE, UPPER_JUDGE
    from imm_model.outputs import Output, plan_outputs
    from imm_model.paths import SAMPLE_DATA, SAMPLE_JUDGE, SAMPLE_LOWER_JUDGE, SAMPLE_UPPER_JUDGE

    cfg, default_out = {"follower": (FOLLOWER_JUDGE, SAMPLE_JUDGE), "upper": (UPPER_JUDGE, SAMPLE_UPPER_JUDGE),
                        "lower": (LOWER_JUDGE, SAMPLE_LOWER_JUDGE)}[args.inputs]
    data_path = args.data or SAMPLE_DATA
    out = args.out or default_out
    plan_outputs([Output(out), Output(sidecar_path(out), "--out's sidecar")], [data_path], args.force)
    data = InteractionDataset.load(data_path)
    if cfg.inputs == "lower" and not data.skeleton.leg_joints:  # the judge would read the body centre alone
        raise DataFormatError(f"{data_path}: its {data.skeleton.name} skeleton names no legs (body parts ending in 'leg'), "
                              "so a lower-body judge would read none")
    model = fold_classifier(cfg, data, args.fold)
    save_checkpoint(out, model.state_dict(), {"kind": "classifier", "config": cfg.to_dict(), "subject": args.fold,
                                              "class_names": list(data.class_names), "dataset": data.dataset}, args.force)
    read = "follower-only" if cfg.inputs == "follower" else f"follower {cfg.inputs}-body"
    print(f"wrote {out}: {read} {cfg.arch} classifier, subject {args.fold} held out")
    return 0


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, as every other error of the command (the usage is one --help away); subcommands'
    parsers are of this class too."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {printable(message)} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="imm",
        description="IMM Studio: synthesize a follower's reaction to a leader's motion (Interaction Mix and Match).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in dict.fromkeys(COMMAND_MODULES.values()):
        try:
            importlib.import_module(module).register(sub)
        except ModuleNotFoundError as err:
            if not module.startswith(err.name or "\0"):
                raise  # a missing third-party dependency is a real error
    for entry in entry_points(group=PLUGIN_GROUP):
        try:
            entry.load().register(sub)
        except ImportError as err:  # e.g. the studio extra is not installed: say so when it is asked for
            _register_unavailable(sub, entry.name, f"{err} (install the extras: pip install -e '.[studio]')")
    return parser


def _register_unavailable(subparsers: argparse._SubParsersAction, name: str, reason: str) -> None:
    def fail(args: argparse.Namespace) -> int:
        raise IMMError(f"`imm {name}` is not available here: {reason}")

    p = subparsers.add_parser(name, help=f"(not available: {reason})", add_help=False)
    p.set_defaults(func=fail, ignores_extra_arguments=True)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and not getattr(args, "ignores_extra_arguments", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return int(args.func(args) or 0)
    except (IMMError, ValueError, KeyError, OSError) as err:
        msg = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"imm {args.command}: error: {printable(str(msg))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C, or a SIGTERM a command turned into one, once its clean-up has run
        print(f"imm {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
