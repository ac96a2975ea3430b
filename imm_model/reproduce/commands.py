"""`imm reproduce`: train and evaluate everything the paper's four tables need, then write the report.

Every run and evaluation is a job (reproduce/plan.py) run on Ray (reproduce/runner.py); finished ones are
reused, so a killed reproduce is simply started again with the same arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path


def _int_list(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, not {text!r}") from None


def _name_list(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def register(subparsers: argparse._SubParsersAction) -> None:
    from imm_model.reproduce.plan import MODEL_RECIPES, PAPER_TABLES, SBU_SUBJECTS, TABLES

    p = subparsers.add_parser(
        "reproduce", help="the paper's four tables (AFD, FID, ablation, recognition): every run on Ray, resumable",
        description="Trains every run the tables need (7 LOSO folds x recipes x seeds, and the recognition study's half "
                    "split) as Ray tasks, evaluates them, and writes OUT/report.md with the paper's numbers beside ours. "
                    "Finished runs are reused (keyed by config, split, seed and data): rerun the same command after an "
                    "interruption. docs/reproduction.md explains local and cluster use.")
    p.add_argument("--out", type=Path, required=True, help="report folder: report.md, summary.json, figures")
    p.add_argument("--runs", type=Path, default=None, help="where the training runs go (default OUT/runs)")
    p.add_argument("--seeds", type=_int_list, default=(0,), help="comma-separated training seeds (default 0)")
    p.add_argument("--tables", type=_name_list, default=PAPER_TABLES,
                   help=f"comma-separated subset of {','.join(TABLES)} (default: the paper's four; 'models' compares "
                        f"{' and '.join(MODEL_RECIPES)} with the 1-NN, dev and test folds apart)")
    p.add_argument("--folds", type=_name_list, default=SBU_SUBJECTS, help="comma-separated LOSO subjects (default all 7)")
    p.add_argument("--address", default=None, help="join this Ray cluster (default: start Ray on this machine)")
    p.add_argument("--cpus-per-task", type=int, default=1, help="CPUs (torch threads) per job (default 1)")
    p.add_argument("--backend", choices=("auto", "ray", "local"), default="auto",
                   help="auto: Ray when installed, else local processes")
    p.add_argument("--data", type=Path, default=None, help="SBU bundle (default: the bundled one)")
    p.add_argument("--report-only", action="store_true",
                   help="write the report from the runs and evaluations already finished, start nothing (an interim "
                        "report while a cluster works; what is not done is listed under Missing)")
    p.add_argument("--epochs", type=int, default=None, help=argparse.SUPPRESS)  # tiny runs in tests
    p.add_argument("--classifier-epochs", type=int, default=None, help=argparse.SUPPRESS)
    p.set_defaults(func=_cmd_reproduce)


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from imm_model.data.dataset import InteractionDataset, dataset_hash
    from imm_model.outputs import FolderLock, Output, plan_outputs
    from imm_model.paths import SAMPLE_DATA, k3hi_raw_root
    from imm_model.reproduce.jobs import copy_records
    from imm_model.reproduce.plan import ReproducePlan
    from imm_model.reproduce.report import REPORT_FILES, write_report
    from imm_model.reproduce.runner import Runner

    t0 = time.perf_counter()
    plan = ReproducePlan(seeds=args.seeds, tables=args.tables, folds=args.folds, epochs=args.epochs,
                         classifier_epochs=args.classifier_epochs, k3hi=k3hi_raw_root().is_dir())
    if not plan.k3hi and "fid" in plan.tables:
        print(f"K3HI not found at {k3hi_raw_root()}: the MoCap FID table is left out")
    data_path = (args.data or SAMPLE_DATA).resolve()
    data_hash = {"sbu": dataset_hash(InteractionDataset.load(data_path))}
    if plan.k3hi and "fid" in plan.tables:
        from imm_model.reproduce.k3hi_table import shared_data

        data_hash["k3hi"] = dataset_hash(shared_data()[0])
    runs = (args.runs or args.out / "runs").resolve()
    plan_outputs([Output(args.out / name, "--out") for name in REPORT_FILES], [data_path], force=True)  # rewritten on reruns
    with contextlib.ExitStack() as locks:
        locks.enter_context(FolderLock(args.out, "--out"))
        if args.report_only:  # reads the runs, which another reproduce may be training
            trained, results = _run_jobs(None, plan, runs, data_path, data_hash, args.cpus_per_task)
        else:
            runner = Runner(args.address, args.cpus_per_task, args.backend)  # checks its arguments; starts nothing yet
            locks.enter_context(FolderLock(runs, "--runs"))
            with runner:
                trained, results = _run_jobs(runner, plan, runs, data_path, data_hash, args.cpus_per_task)
        wall = time.perf_counter() - t0
        report = write_report(plan, results, args.out.resolve(), None if args.report_only else wall, runs)
        records = copy_records(plan.training_jobs(), runs, args.out.resolve() / "records")
    failed = len(plan.training_jobs()) - len(trained) + sum(1 for r in results.values() if r is None)
    how = ["report only" if args.report_only else f"{wall / 60:.1f} min wall"]
    how += [f"{failed} jobs {'not done' if args.report_only else 'failed'}"] if failed else []
    print(f"report: {report} ({'; '.join(how)}); "
          f"the records of {records} runs (no checkpoints) in {args.out / 'records'}")
    return 1 if failed else 0


def _run_jobs(runner, plan, runs: Path, data_path: Path, data_hash: dict[str, str], cpus: int) -> tuple[set, dict]:
    """Every training run not finished yet, and every evaluation not cached, as one list of jobs: an evaluation starts
    as soon as its runs have finished (runner None: nothing is run).
    -> (finished training jobs, {EvalJob: result, or None if it could not run})."""
    from imm_model.reproduce.jobs import run_status
    from imm_model.reproduce.runner import Task
    from imm_model.reproduce.tasks import cached_result, evaluate_run, train_run

    keys = {job: job.key(data_hash[job.dataset]) for job in plan.training_jobs()}
    status = {job: run_status(job, runs, key) for job, key in keys.items()}
    finished = {job for job, s in status.items() if s == "done"}
    todo = [job for job in keys if job not in finished]  # the runner starts the longest first (Task.cost)
    resumed = sum(status[j] == "partial" for j in todo)
    print(f"{len(keys)} training runs: {len(finished)} finished already (reused), {resumed} to resume, "
          f"{len(todo) - resumed} to train")
    describe = lambda info: f"{info['epochs']} epochs (best {info['best_epoch']}) in {info['seconds']:.0f} s"  # noqa: E731
    tasks = [Task(job.name, train_run, (job, runs, data_path, keys[job], cpus), describe, cost=job.cost) for job in todo]
    index = {job: i for i, job in enumerate(todo)}
    evals = plan.eval_jobs()
    results: dict = {j: None for j in evals}
    results |= {j: cached_result(j, runs) for j in evals if all(run in finished for run in j.needs)}
    eval_todo = [j for j in evals if results[j] is None]
    print(f"{len(evals)} evaluations: {len(evals) - len(eval_todo)} reused, {len(eval_todo)} to run")
    tasks += [Task(j.name, evaluate_run, (j, runs, data_path, cpus), lambda r: "done",
                   needs=tuple(index[run] for run in j.needs if run in index), cost=j.cost) for j in eval_todo]
    if runner is None:  # --report-only
        print(f"report only: {len(todo)} training runs and {len(eval_todo)} evaluations not done are left out")
        return finished, results
    outcomes = runner.run(tasks, "jobs")
    finished |= {job for job, (ok, _) in zip(todo, outcomes, strict=False) if ok}
    results |= {j: (value if ok else None) for j, (ok, value) in zip(eval_todo, outcomes[len(todo):], strict=True)}
    return finished, results
