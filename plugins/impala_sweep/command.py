"""``impala-flow sweep SWEEP.yaml -o DIR``: a graph over missions, seeds and parameter variants on Dask."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from impala_flow.cli import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, CommandError
from impala_flow.cli.helpers import open_session

from .spec import MAX_TASKS, MAX_TASKS_CEILING


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep", help="run a graph over many missions, seeds and parameter variants (Dask)",
        description="Run the graph of SWEEP.yaml once per (mission, variant, seed, repeat) on Dask distributed: "
        "a local cluster of worker processes by default, or the cluster of --scheduler. Writes DIR/results.csv "
        "(one row per task: mission, seed, parameters, metrics, counters, wall time, status, error), "
        "DIR/summary.md (mean ± std per variant), DIR/variants.png (a box plot per metric) and each task's "
        "folder DIR/tasks/<task>/ (the graph's ${out}). A task that fails is recorded and the sweep goes on "
        "(exit 1 at the end); Ctrl-C keeps what is done (exit 130); --resume DIR runs what is left.",
        epilog="examples:\n  impala-flow sweep graphs/sweeps/rslam-search.yaml -o out/sweep\n"
        "  impala-flow sweep graphs/sweeps/rslam-search.yaml -o out/sweep --scheduler tcp://10.0.0.5:8786\n"
        "  impala-flow sweep graphs/sweeps/rslam-search.yaml --resume out/sweep",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("sweep", metavar="SWEEP.yaml", help="sweep file: graph, missions, grid or variants, metrics")
    p.add_argument("-o", "--output", metavar="DIR", help="folder of the results (on shared storage for a cluster: "
                   "the workers write the task folders there)")
    p.add_argument("--resume", metavar="DIR", help="continue the sweep of DIR: tasks with an ok row in "
                   "DIR/results.csv are skipped, the others run; refused unless DIR was made by this same sweep "
                   "(sweep file, graph and missions unchanged)")
    p.add_argument("--overwrite", action="store_true", help="use -o DIR although it is not empty: a sweep's "
                   "folder is started again (only what that sweep made is removed); another folder gets the sweep "
                   "beside what is there, refused if a file the sweep writes is there already")
    p.add_argument("--max-tasks", type=int, default=None, metavar="N",
                   help="most tasks the sweep may expand to (missions x variants x repeats, counted before "
                   "anything is built; default " + str(MAX_TASKS) + ")")
    p.add_argument("--dashboard", metavar="HOST:PORT", default=None,
                   help="where the local cluster's Dask dashboard listens (default 127.0.0.1:8787, this machine "
                   "only, another port when taken; 0.0.0.0:8787 opens it to the network; none: no dashboard)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler (tcp://host:8786) "
                   "instead of a local cluster")
    p.add_argument("--scheduler-file", metavar="FILE", help="the scheduler's file (dask scheduler "
                   "--scheduler-file FILE) instead of its address")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local cluster (default: one per CPU)")
    p.add_argument("--threads-per-worker", type=int, default=1, metavar="T",
                   help="threads per worker process of the local cluster (default 1: the graphs are CPU-bound "
                   "numpy, one process per core runs them side by side)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar nor per-task lines")
    p.set_defaults(func=run)


def _check_args(args: argparse.Namespace) -> Path:
    if args.output and args.resume and Path(args.output).resolve() != Path(args.resume).resolve():
        raise CommandError(f"-o {args.output} and --resume {args.resume}: two different folders", EXIT_USAGE)
    out = args.resume or args.output
    remote = args.scheduler or args.scheduler_file
    if not out:
        raise CommandError("give the results folder: -o DIR (or --resume DIR)", EXIT_USAGE)
    if args.resume and args.overwrite:
        raise CommandError("--resume and --overwrite: give one (resume keeps what is done, overwrite starts again)",
                           EXIT_USAGE)
    if args.max_tasks is not None and not 1 <= args.max_tasks <= MAX_TASKS_CEILING:
        raise CommandError(f"--max-tasks {args.max_tasks}: must be between 1 and {MAX_TASKS_CEILING}", EXIT_USAGE)
    if args.dashboard is not None and remote:
        raise CommandError("--dashboard places the local cluster's dashboard; with --scheduler the scheduler "
                           "has its own", EXIT_USAGE)
    if args.scheduler and args.scheduler_file:
        raise CommandError("--scheduler and --scheduler-file: give one", EXIT_USAGE)
    if remote and (args.workers is not None or args.threads_per_worker != 1):
        raise CommandError("--workers and --threads-per-worker size the local cluster; with --scheduler the "
                           "cluster's own workers run the tasks", EXIT_USAGE)
    if args.workers is not None and args.workers < 1:
        raise CommandError(f"--workers {args.workers}: must be >= 1", EXIT_USAGE)
    if args.threads_per_worker < 1:
        raise CommandError(f"--threads-per-worker {args.threads_per_worker}: must be >= 1", EXIT_USAGE)
    if Path(out).exists() and not Path(out).is_dir():
        raise CommandError(f"{out}: not a folder", EXIT_USAGE)
    if args.resume and not Path(out).is_dir():
        raise CommandError(f"--resume {out}: no such folder (nothing to resume)", EXIT_USAGE)
    return Path(out)


def run(args: argparse.Namespace) -> int:
    from impala_flow import GraphError

    from .check import check_sweep
    from .spec import SweepError, load_sweep
    from .task import one_line

    out = _check_args(args)
    try:
        spec = load_sweep(args.sweep, max_tasks=args.max_tasks or MAX_TASKS)
    except SweepError as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    session = open_session()
    try:
        check_sweep(spec, session, out)
        if args.scheduler:
            from .runner import parse_scheduler

            parse_scheduler(args.scheduler)
    except (GraphError, SweepError) as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    try:
        import distributed  # noqa: F401  - lazily: only a sweep needs Dask
    except ImportError as e:
        raise CommandError(f"sweeps need Dask distributed: pip install 'dask[distributed]' ({e})") from None
    from .runner import DASHBOARD, run_sweep

    try:
        outcome = run_sweep(spec, out, scheduler=args.scheduler, scheduler_file=args.scheduler_file,
                            workers=args.workers, threads_per_worker=args.threads_per_worker,
                            resume=bool(args.resume), overwrite=args.overwrite,
                            dashboard=args.dashboard or DASHBOARD, progress=False if args.no_progress else None)
    except SweepError as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    except (OSError, TimeoutError) as e:
        where = args.scheduler or args.scheduler_file or "the local cluster"
        raise CommandError(f"Dask ({where}): {type(e).__name__}: {one_line(e)}", EXIT_FAILED) from None
    ran = outcome.ok + outcome.failed
    print(f"sweep {spec.path.name}: {outcome.total} tasks, {outcome.ok} ok, {outcome.failed} failed"
          + (f", {outcome.skipped} done before" if outcome.skipped else "")
          + (f", {outcome.total - ran} not run" if outcome.total > ran else "")
          + f" ({outcome.wall_s:.1f} s)")
    for label, name in (("results", "results.csv"), ("summary", "summary.md"), ("figure", "variants.png"),
                        ("tasks", "tasks")):
        if (out / name).exists():
            print(f"  {label + ':':9s}{out / name}")
    if outcome.interrupted:
        print(f"impala-flow sweep: interrupted; {outcome.ok} of {outcome.total} tasks done, resume with "
              f"--resume {out}", file=sys.stderr)
        return EXIT_INTERRUPTED
    if outcome.failed:
        print(f"impala-flow sweep: {outcome.failed} of {outcome.total} tasks failed (errors in {out}/results.csv "
              "and summary.md)", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
