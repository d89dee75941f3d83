#!/usr/bin/env python3
"""Kill-and-resume soak (issue 42, point 3): stops runs again and again at seeded random steps and
places, resumes them, and checks that each finished run wrote bit for bit what a run never stopped
wrote (stats.csv but for wall_seconds, scene.pvd and every frame).

    /usr/bin/python3 scripts/soak_resume.py [--cycles 100] [--seed 1] [--steps 60] [--every 4]
                                            [--scene scenes/stress/pile_100.json ...] [--work DIR]

Each round runs one scene afresh and stops it several times before it ends. A stop is the test hook
NEXDYN_TEST_SIGNAL (engine/run.hpp): SIGKILL as a step begins, after its stats row, just after a
checkpoint file is in place, or inside the step at a Newton iteration; or SIGTERM / SIGINT at a
Newton iteration (the step is abandoned and the run exits 143 / 130 with a checkpoint); with
--timed P, a share P of the stops is SIGTERM sent after a random time instead, which lands at
whichever safe point comes next (a CCD batch, a line-search trial, a factorisation). Each stop
is one cycle; after it the run is resumed (or run afresh when no checkpoint was written yet), on 1
or 2 threads drawn at random. The rounds go round the scenes until --cycles stops are done.

The suite runs a short version of the same on pile_100 and mat_40
(tests/engine/cli/test_resume_cli.cpp). Prints one line per round and a summary; exits 1 if any
round differs from its reference, naming the first step that differs.
"""
import argparse
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
DEFAULT_SCENES = ["scenes/stress/pile_100.json", "scenes/stress/mat_40.json"]


def run(nexdyn, args, hook=None, term_after=None):
    """Runs nexdyn with the test hook `hook`, or sends it SIGTERM after `term_after` seconds."""
    env = {k: v for k, v in os.environ.items() if k != "NEXDYN_TEST_SIGNAL"}
    if hook:
        env["NEXDYN_TEST_SIGNAL"] = hook
    child = subprocess.Popen([str(nexdyn)] + args + ["--quiet"], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
    if term_after is not None:
        try:
            child.wait(timeout=term_after)
        except subprocess.TimeoutExpired:
            child.send_signal(signal.SIGTERM)
    _, err = child.communicate()
    return child.returncode, err


def outputs(folder):
    """What a finished run wrote that must not depend on being stopped: by file name."""
    rows = (folder / "stats.csv").read_text().splitlines()
    wall = rows[0].split(",").index("wall_seconds")
    files = {"stats.csv": [",".join(f for i, f in enumerate(r.split(",")) if i != wall) for r in rows]}
    for path in [folder / "scene.pvd"] + sorted((folder / "frames").glob("*")):
        if path.is_file():
            files[str(path.relative_to(folder))] = path.read_bytes()
    return files


def first_difference(expected, got):
    if expected.keys() != got.keys():
        return "the files differ: " + " ".join(sorted(set(expected) ^ set(got)))
    for row_a, row_b in zip(expected["stats.csv"], got["stats.csv"]):
        if row_a != row_b:
            return "stats.csv differs from step " + row_b.split(",")[0]
    for name in expected:
        if expected[name] != got[name]:
            return name + " differs"
    return None


def newest_checkpoint(folder):
    """The step of the newest checkpoint in the folder, 0 without one."""
    steps = [int(p.stem.split("_")[1]) for p in (folder / "checkpoints").glob("checkpoint_*.ckpt")] \
        if (folder / "checkpoints").is_dir() else []
    return max(steps, default=0)


def rows(folder):
    """Data rows of stats.partial.csv, 0 without it."""
    path = folder / "stats.partial.csv"
    return max(0, len(path.read_text().splitlines()) - 1) if path.exists() else 0


def has_checkpoint(folder):
    return any((folder / "checkpoints").glob("checkpoint_*.ckpt")) if (folder / "checkpoints").is_dir() else False


def stop_plan(rng, steps, every, count):
    """`count` stops at increasing steps in [1, steps - 1]: (step, signal, place)."""
    stops, previous = [], 0
    for k in range(count):
        if previous >= steps - 1:
            break
        last = max(previous + 1, previous + (steps - 1 - previous) // (count - k))
        step = rng.randint(previous + 1, last)
        kind = rng.choice(["KILL:begin", "KILL:row", "KILL:checkpoint", "KILL:newton", "TERM:newton", "INT:newton"])
        name, place = kind.split(":")
        if place == "checkpoint":
            step = -(-step // every) * every
            if step > steps - 1:
                place = "row"
                step = min(max(previous + 1, step - every), steps - 1)
        if place == "newton":
            place += str(rng.randint(1, 3))
        stops.append((step, name, place))
        previous = step
    return stops


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=100, help="stops in all (default 100)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=60, help="steps of each run (default 60)")
    parser.add_argument("--every", type=int, default=4, help="steps between checkpoints (default 4)")
    parser.add_argument("--stops", type=int, default=5, help="stops per round (default 5)")
    parser.add_argument("--scene", action="append", help="scenes to soak (default pile_100 and mat_40)")
    parser.add_argument("--timed", type=float, default=0.0, metavar="P",
                        help="with probability P a stop is instead SIGTERM sent after a random 0.2 to 3 s, "
                             "wherever the run is then (default 0: every stop by the hook)")
    parser.add_argument("--nexdyn", default=str(ROOT / "build" / "nexdyn"))
    parser.add_argument("--work", help="folder for the runs (default a temporary one, removed)")
    a = parser.parse_args()
    scenes = [ROOT / s for s in (a.scene or DEFAULT_SCENES)]
    work = pathlib.Path(a.work) if a.work else pathlib.Path(tempfile.mkdtemp(prefix="nexdyn-soak-"))
    rng = random.Random(a.seed)
    start = time.time()
    references = {}
    for scene in scenes:
        folder = work / (scene.stem + "-reference")
        code, err = run(a.nexdyn, ["run", str(scene), "--steps", str(a.steps), "--checkpoint-every", str(a.every),
                                   "--threads", "2", "--out", str(folder)])
        if code != 0:
            sys.exit(f"{scene}: the reference run failed ({code}): {err.strip()}")
        references[scene] = outputs(folder)
    cycles = rounds = resumes = 0
    failures = []
    while cycles < a.cycles:
        scene = scenes[rounds % len(scenes)]
        rounds += 1
        folder = work / (scene.stem + "-soak")
        shutil.rmtree(folder, ignore_errors=True)
        fresh = ["run", str(scene), "--steps", str(a.steps), "--checkpoint-every", str(a.every), "--out", str(folder)]
        plan = stop_plan(rng, a.steps, a.every, min(a.stops, a.cycles - cycles))
        trail = []
        for step, name, place in plan:
            threads = str(rng.choice([1, 2]))
            resuming = has_checkpoint(folder)
            resumes += resuming
            args = (["resume", str(folder)] if resuming else fresh) + ["--threads", threads]
            if rng.random() < a.timed:  # wherever the run is after a while: any safe point
                delay = rng.uniform(0.2, 3.0)
                start_step, rows_before = (newest_checkpoint(folder) if resuming else 0), rows(folder)
                code, err = run(a.nexdyn, args, term_after=delay)
                name, trail_entry = "TERM", f"TERM after {delay:.2f} s"
            else:
                code, err = run(a.nexdyn, args, f"{name}@{step}:{place}")
                trail_entry = f"{name}@{step}:{place}"
            expected = {"KILL": -signal.SIGKILL, "TERM": 128 + signal.SIGTERM, "INT": 128 + signal.SIGINT}[name]
            if trail_entry.startswith("TERM after") and code == -signal.SIGTERM and \
                    rows(folder) in (start_step, rows_before):
                # It came while the scene loaded, before the run's first step (no row was written
                # past the checkpoint): the system's default action. A run killed by it later fails.
                expected = code
            trail.append(f"{trail_entry}/{threads}t")
            if code == 0 and (folder / "stats.csv").exists():
                trail[-1] += "(ran to the end first: fewer Newton iterations, or the delay too long)"
                break
            if code != expected:
                failures.append(f"{scene.name} round {rounds}: {trail[-1]} ended with {code}, not {expected}: "
                                f"{err.strip()[-300:]}")
            cycles += 1
        code = 0
        if not (folder / "stats.csv").exists():
            threads = str(rng.choice([1, 2]))
            resuming = has_checkpoint(folder)
            resumes += resuming
            code, err = run(a.nexdyn, (["resume", str(folder)] if resuming else fresh) + ["--threads", threads])
        why = f"the last run ended with {code}: {err.strip()[-300:]}" if code != 0 else \
            first_difference(references[scene], outputs(folder))
        print(f"round {rounds} {scene.stem}: {' '.join(trail)} -> {'same' if why is None else why}", flush=True)
        if why is not None:
            failures.append(f"{scene.name} round {rounds} ({' '.join(trail)}): {why}")
    print(f"{cycles} stops in {rounds} rounds ({resumes} resumes) over {len(scenes)} scenes, "
          f"{time.time() - start:.0f} s: {len(failures)} failures")
    for failure in failures:
        print("  " + failure)
    if not a.work:
        shutil.rmtree(work, ignore_errors=True)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
