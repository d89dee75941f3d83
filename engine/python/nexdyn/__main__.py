"""`python3 -m nexdyn sweep SCENE --set KEY=V1,V2,... [--set ...] --out DIR [--scheduler ADDRESS]
[--workers N] [--steps N]`: a parameter sweep on Dask (nexdyn.sweep; docs/python.md).

Exit codes, as nexdyn's (README, "Exit codes"): 0 when every run is done; 1 when some failed, or
when nothing was run because of bad input (a bad key or value, a scene the engine refuses, a
folder holding another sweep, a scheduler that cannot be reached); 2 for a usage error (the
command line itself); 130 on Ctrl-C (the same command resumes the sweep).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any, Dict, List, Optional, Tuple

KEY_RULES = """\
KEY is a dotted path into the scene: contact.friction, time.dt, bodies.0.velocity (an integer
indexes a list; every part but the last must exist in the scene). V1,V2,... are split on the
commas outside brackets and double quotes, so bodies.0.velocity=[0,-1,0],[0,-2,0] is two values.
Each value is JSON when it parses (0.1, true, [0,-1,0], {"a":1}, "text"); anything else is a
string (stvk). The runs are the product of the --set lists, the last varying fastest.

Run k is DIR/runs/kkkk/ (its scene.json, then what `nexdyn run` writes); DIR/sweep.csv has a row
per run. The same command again skips finished runs and resumes interrupted ones.
exit codes: 0 every run done, 1 some failed or bad input (key, scene, folder or scheduler: nothing
run), 2 usage, 130 Ctrl-C"""


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _parsers() -> Tuple[argparse.ArgumentParser, argparse.ArgumentParser]:
    parser = argparse.ArgumentParser(prog="nexdyn", description="NexDynIPC from Python.")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sweep = commands.add_parser(
        "sweep", help="run the product of parameter values on a Dask cluster",
        description="Run the product of parameter values of a scene on a Dask cluster (a local one by default).",
        epilog=KEY_RULES, formatter_class=argparse.RawDescriptionHelpFormatter)
    sweep.add_argument("scene", metavar="SCENE", help="scene JSON file")
    sweep.add_argument("--set", dest="sets", action="append", required=True, metavar="KEY=V1,V2,...",
                       help="a key and its values (repeatable)")
    sweep.add_argument("--out", required=True, metavar="DIR", help="the sweep's folder")
    sweep.add_argument("--scheduler", metavar="ADDRESS",
                       help="a Dask scheduler (tcp://HOST:8786, or its --scheduler-file) instead of a local cluster")
    sweep.add_argument("--workers", type=_positive, metavar="N",
                       help="processes of the local cluster (default: the number of cores)")
    sweep.add_argument("--steps", type=_positive, metavar="N", help="every run's length (default: the scene's time.steps)")
    return parser, sweep


def _progress(k: int, n: int, assignments: str, result: Dict[str, Any]) -> None:
    width = len(str(n))
    line = f"[{k:{width}d}/{n}] run {result['number']:04d} {result['status']:6s} {assignments}: " \
           f"{result['steps']} steps, {result['wall_seconds']:.2f} s"
    if result["skipped"]:
        line += ", finished before"
    elif result["resumed_from"] is not None:
        line += f", resumed from step {result['resumed_from']}"
    if result["reason"]:
        line += f": {result['reason']}"
    print(line, flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    parser, sweep_parser = _parsers()
    args = parser.parse_args(argv)

    from . import SceneError
    from .sweep_runs import SchedulerError, _Sweep, parse_set

    params: Dict[str, List[Any]] = {}
    for argument in args.sets:
        try:
            key, values = parse_set(argument)
        except ValueError as e:
            sweep_parser.error(str(e))
        if key in params:
            sweep_parser.error(f"--set {key} is given twice; put all its values in one --set")
        params[key] = values
    if args.workers is not None and args.scheduler is not None:
        sweep_parser.error("--workers sizes a local cluster; with --scheduler the cluster's own workers run the sweep")

    try:
        job = _Sweep(args.scene, params, args.out, args.steps, None, args.scheduler, args.workers)
    except (SceneError, ValueError) as e:
        print(f"nexdyn sweep: {e}", file=sys.stderr)
        return 1
    where = args.scheduler or f"a local cluster of {args.workers or os.cpu_count() or 1} workers"
    print(f"nexdyn sweep: {len(job.plan)} runs of {args.scene} into {job.plan.out} on {where}", flush=True)
    try:
        rows = job.run(progress=_progress)
    except SchedulerError as e:
        print(f"nexdyn sweep: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("\nnexdyn sweep: interrupted; the same command resumes the sweep", file=sys.stderr)
        return 130
    failed = sum(row["status"] != "done" for row in rows)
    print(f"nexdyn sweep: {len(rows) - failed} of {len(rows)} runs done"
          f"{f', {failed} failed' if failed else ''}; {job.plan.out}/sweep.csv", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
