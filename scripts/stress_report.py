#!/usr/bin/env python3
"""Measures a scene for the performance report (issue 5): one row per thread count.

Runs `nexdyn run` under /usr/bin/time -v with each thread count (default 2 and 1), reads
stats.csv and timings.csv, and prints a Markdown table: ms per step, steps per second, Newton
iterations per step, microseconds per DOF per step and per Newton iteration, peak resident
memory (also per tet, with and without the Cholesky factors), and the time of every stage per
step; then the 2-thread speed-up of every stage. It also
checks that the run stayed intersection-free (min_distance > 0 on every step) and that 1 and 2
threads gave the same statistics bit for bit.

    python3 scripts/stress_report.py scenes/stress/pile_1000.json --steps 10
    python3 scripts/stress_report.py scenes/mat40x40_twist.json --nexdyn /tmp/build/nexdyn

Standard library only.
"""
import argparse
import csv
import json
import pathlib
import re
import subprocess
import sys
import tempfile

STAGES = ["broad_phase", "ccd", "barrier", "friction", "elastic", "analysis", "factorisation",
          "solve", "line_search", "measure", "other", "output"]


def run(nexdyn, scene, steps, threads, out):
    command = ["/usr/bin/time", "-v", nexdyn, "run", str(scene), "--out", str(out),
               "--threads", str(threads)]
    if steps:
        command += ["--steps", str(steps)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    peak_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr).group(1))
    factor_mb = float(re.search(r"peak Cholesky factors ([0-9.e+-]+) MB", done.stdout + done.stderr).group(1))
    with open(out / "stats.csv") as f:
        stats = list(csv.DictReader(f))
    with open(out / "timings.csv") as f:
        timings = list(csv.DictReader(f))
    return stats, timings, peak_kb, factor_mb


def summary(stats, timings, peak_kb, factor_mb, dofs, tets):
    steps = len(timings)
    total_ms = sum(float(r["total_ms"]) for r in timings)
    iterations = sum(int(r["newton_iterations"]) for r in stats)
    per_step = total_ms / steps
    return {
        "ms_per_step": per_step,
        "steps_per_s": 1e3 / per_step,
        "its_per_step": iterations / steps,
        "us_per_dof_step": 1e3 * per_step / dofs,
        "ms_per_iteration": total_ms / max(iterations, 1),
        "peak_mb": peak_kb / 1024.0,
        "factor_mb": factor_mb,
        # peak memory per tet, and what is left of it once the factors are taken out
        "kb_per_tet": peak_kb * 1024.0 / tets / 1e3,
        "kb_per_tet_without_factors": (peak_kb * 1024.0 - factor_mb * 1024.0 * 1024.0) / tets / 1e3,
        "stages": {s: sum(float(r[s + "_ms"]) for r in timings) / steps for s in STAGES},
        "min_distance": min(float(r["min_distance"]) for r in stats),
    }


def scene_size(nexdyn, scene):
    text = subprocess.run([nexdyn, "check", str(scene)], capture_output=True, text=True, check=True).stdout
    dofs = int(re.search(r"DOFs (\d+)", text).group(1))
    tets = int(re.search(r"tets (\d+)", text).group(1))
    return dofs, tets


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", type=pathlib.Path)
    parser.add_argument("--steps", type=int, default=0, help="steps to run (default: the scene's)")
    parser.add_argument("--threads", type=int, nargs="+", default=[2, 1])
    parser.add_argument("--nexdyn", default="build/nexdyn")
    args = parser.parse_args()

    dofs, tets = scene_size(args.nexdyn, args.scene)
    results, stats_by_threads = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for threads in args.threads:
            stats, timings, peak_kb, factor_mb = run(args.nexdyn, args.scene, args.steps, threads,
                                                     pathlib.Path(tmp) / f"t{threads}")
            results[threads] = summary(stats, timings, peak_kb, factor_mb, dofs, tets)
            stats_by_threads[threads] = [{k: v for k, v in r.items() if k != "wall_seconds"} for r in stats]

    print(f"{args.scene} ({dofs} DOFs, {tets} tets, {len(stats)} steps)\n")
    print("| threads | ms / step | steps / s | Newton its / step | ms / Newton it | us / DOF / step | "
          "peak RSS MB | factors MB | KB / tet | KB / tet without factors | min distance m |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for threads, r in results.items():
        print(f"| {threads} | {r['ms_per_step']:.1f} | {r['steps_per_s']:.2f} | {r['its_per_step']:.1f} | "
              f"{r['ms_per_iteration']:.2f} | {r['us_per_dof_step']:.3f} | {r['peak_mb']:.0f} | "
              f"{r['factor_mb']:.0f} | {r['kb_per_tet']:.2f} | {r['kb_per_tet_without_factors']:.2f} | "
              f"{r['min_distance']:.3g} |")
    print("\n| stage (ms / step) | " + " | ".join(f"{t} thread{'s' if t > 1 else ''}" for t in results) +
          (" | speed-up |" if 1 in results and 2 in results else " |"))
    print("| --- | " + " | ".join("---" for _ in results) + (" | --- |" if 1 in results and 2 in results else " |"))
    for stage in STAGES + ["total"]:
        values = {t: (r["ms_per_step"] if stage == "total" else r["stages"][stage]) for t, r in results.items()}
        row = f"| {stage} | " + " | ".join(f"{v:.1f}" for v in values.values())
        if 1 in values and 2 in values:
            row += f" | {values[1] / values[2]:.2f}x" if values[2] > 0.05 else " | -"
        print(row + " |")
    if len(stats_by_threads) > 1:
        first = next(iter(stats_by_threads.values()))
        same = all(s == first for s in stats_by_threads.values())
        print(f"\nstats.csv equal on {', '.join(map(str, stats_by_threads))} threads (all columns but "
              f"wall_seconds): {'yes' if same else 'NO'}")
    if any(r["min_distance"] <= 0.0 for r in results.values()):
        print("WARNING: min_distance reached 0")


if __name__ == "__main__":
    main()
