#!/usr/bin/env python3
"""Runs every shipped scene (scenes/*.json and scenes/stress/*.json) with two nexdyn programs and
says whether their stats.csv agree bit for bit, wall_seconds aside: the check a refactoring that
must not change any result is held to (issue 39).

    python3 scripts/same_stats.py BEFORE AFTER [--steps N] [--threads K] [--only NAME ...]

BEFORE and AFTER are nexdyn programs (build one from the commit before the change into another
folder, or copy build/nexdyn aside before rebuilding). Each scene runs N steps (default 20; the
largest stress scenes fewer, see LONG) in a temporary folder. Prints one line per scene and exits
1 if any differs.
"""
import argparse
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
# Scenes whose steps take seconds: fewer steps keep the check to minutes.
LONG = {"pile_1000": 5, "mat100x100_twist": 5, "roller": 10}


def stats_without_wall_seconds(path):
    rows = path.read_text().splitlines()
    header = rows[0].split(",")
    wall = header.index("wall_seconds")
    return [",".join(f for i, f in enumerate(row.split(",")) if i != wall) for row in rows]


def run(program, scene, steps, threads, out):
    command = [str(program), "run", str(scene), "--steps", str(steps), "--threads", str(threads), "--quiet",
               "--out", str(out)]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        # The message names the run's own folder: compare it with that folder left out.
        return None, (result.stderr.strip() or result.stdout.strip()).replace(str(out), "OUT")
    return stats_without_wall_seconds(out / "stats.csv"), ""


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("before", type=pathlib.Path)
    parser.add_argument("after", type=pathlib.Path)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--only", nargs="*", help="scene names (file stems) to run, default all")
    args = parser.parse_args()
    scenes = sorted((ROOT / "scenes").glob("*.json")) + sorted((ROOT / "scenes" / "stress").glob("*.json"))
    if args.only:
        scenes = [s for s in scenes if s.stem in args.only]
    differing = 0
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            steps = min(args.steps, LONG.get(scene.stem, args.steps))
            name = scene.relative_to(ROOT / "scenes")
            a, error_a = run(args.before, scene, steps, args.threads, pathlib.Path(tmp) / "before" / scene.stem)
            b, error_b = run(args.after, scene, steps, args.threads, pathlib.Path(tmp) / "after" / scene.stem)
            if a is None or b is None:
                same = (a is None) == (b is None) and error_a == error_b
                verdict = "same failure" if same else "DIFFERENT: " + (error_a or "ok") + " / " + (error_b or "ok")
            else:
                same = a == b
                first = next((k for k in range(min(len(a), len(b))) if a[k] != b[k]), None)
                verdict = (f"same {len(a) - 1} rows" if same else f"DIFFERENT from row {first}" if first is not None
                           else f"DIFFERENT row counts {len(a)} / {len(b)}")
            differing += not same
            print(f"{str(name):32s} {steps:3d} steps: {verdict}", flush=True)
    print(f"{len(scenes) - differing} of {len(scenes)} scenes the same")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
