#!/usr/bin/env python3
"""Violent impacts under each time integrator (issue 16).

Throws a soft ball (the IPC sphere1K mesh scaled to 0.1 m radius) straight down, and a torus
(torus.msh scaled to 0.2 m across, tilted) at 30 degrees from the vertical, onto the clamped thin
plate of scenes/impact_plate.json at several speeds, under several integrators, and prints one
Markdown table row per run: whether all steps completed, the largest rise of the total energy
above its initial value (growth; gravity and contact included, the boundaries are fixed and do
no work), the smallest distance ever seen, Newton iterations per step (mean and largest), and
the steps the energy guard retook. Named schemes run alone (--energy-guard off) unless written
NAME+guard; "default" is the scene's own choice (generalized-alpha 0.5 with the guard).

    python3 scripts/impact_sweep.py                      # the full sweep, 2 runs at a time
    python3 scripts/impact_sweep.py --speeds 30 --shapes ball --integrators newmark
    python3 scripts/impact_sweep.py --integrators default generalized_alpha:0.8+guard
    python3 scripts/impact_sweep.py --nexdyn /tmp/build/nexdyn --out /tmp/sweep --jobs 1

Scenes and outputs go to --out (default out/impact_sweep). Standard library only.
"""
import argparse
import concurrent.futures
import csv
import json
import pathlib
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
# Each scheme on its own (energy guard off), then the default (generalized-alpha 0.5 with the energy
# guard on). "NAME+guard" runs a scheme with the guard.
INTEGRATORS = ["newmark", "generalized_alpha:0.9", "generalized_alpha:0.8", "generalized_alpha:0.5",
               "implicit_euler", "default"]


def scene(shape, speed):
    with open(ROOT / "scenes" / "impact_plate.json") as f:
        s = json.load(f)
    meshes = ROOT / "scenes" / "meshes"
    thrown = s["bodies"][1]
    if shape == "ball":
        thrown["mesh"] = str(meshes / "sphere1K.msh")
        thrown["velocity"] = [0.0, -speed, 0.0]
    else:  # a torus thrown at 30 degrees from the vertical, tilted so that its rim lands first
        thrown["mesh"] = str(meshes / "torus.msh")
        thrown["rotate_deg"] = [70.0, 0.0, 20.0]
        thrown["translate"] = [-0.15, 0.35, 0.0]
        thrown["velocity"] = [0.5 * speed, -0.8660254037844386 * speed, 0.0]
    s["name"] = f"impact_{shape}_{speed:g}"
    s["output"] = {"every": 1000}
    return s


def run(nexdyn, out, shape, speed, integrator, steps):
    scheme, plus, _ = integrator.partition("+")
    name, _, rho = scheme.partition(":")
    folder = out / f"{shape}_{speed:g}_{integrator.replace(':', '_').replace('+', '_')}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scene.json"
    path.write_text(json.dumps(scene(shape, speed), indent=1))
    cmd = [nexdyn, "run", str(path), "--quiet", "--threads", "1", "--steps", str(steps), "--out", str(folder / "run")]
    if name != "default":
        cmd += ["--integrator", name, "--energy-guard", "on" if plus else "off"]
    if rho:
        cmd += ["--rho-inf", rho]
    start = time.time()
    result = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.time() - start
    stats = folder / "run" / ("stats.csv" if result.returncode == 0 else "stats.partial.csv")
    rows = list(csv.DictReader(open(stats))) if stats.exists() else []
    if rows:
        first = rows[0]
        # The initial total energy: the first row's total minus the change its step made.
        change = sum(float(first[k]) for k in ("boundary_work", "kappa_energy", "integrator_energy"))
        change -= float(first["friction_dissipated"])
        e0 = float(first["total_energy"]) - change
        growth = max(float(r["total_energy"]) for r in rows) - e0
        iterations = [int(r["newton_iterations"]) for r in rows]
        min_distance = min(float(r["min_distance"]) for r in rows)
        retries = sum(int(r["retries"]) for r in rows)
        contact_energy = [float(r["integrator_energy"]) for r in rows if int(r["contacts"]) > 0]
    else:
        e0, growth, iterations, min_distance, retries, contact_energy = float("nan"), float("nan"), [0], 0.0, 0, []
        rows = []
    return {
        "shape": shape, "speed": speed, "integrator": integrator.replace(":", " ").replace("+guard", " + guard"),
        "completed": result.returncode == 0 and len(rows) == steps, "steps": len(rows), "e0": e0,
        "growth": growth, "mean_iterations": sum(iterations) / max(len(iterations), 1),
        "max_iterations": max(iterations), "retries": retries, "min_distance": min_distance,
        "guarded": sum(int(r["guarded_steps"]) for r in rows),
        "contact_integrator_energy": sum(contact_energy), "seconds": seconds,
        "error": result.stderr.strip().splitlines()[-1] if result.returncode else "",
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--nexdyn", default=str(ROOT / "build" / "nexdyn"))
    parser.add_argument("--out", default=str(ROOT / "out" / "impact_sweep"))
    parser.add_argument("--speeds", type=float, nargs="+", default=[5, 10, 20, 30, 50])
    parser.add_argument("--shapes", nargs="+", default=["ball", "torus"], choices=["ball", "torus"])
    parser.add_argument("--integrators", nargs="+", default=INTEGRATORS,
                        help="preset names; generalized_alpha:RHO for a spectral radius; a name with "
                             "+guard runs with the energy guard on; default: the scene's own choice")
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--jobs", type=int, default=2, help="runs at a time (each on one thread)")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    cases = [(shape, speed, integrator) for shape in args.shapes for speed in args.speeds
             for integrator in args.integrators]
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda c: run(args.nexdyn, out, *c, args.steps), cases))
    print("shape | speed [m/s] | integrator | completed | energy growth [% of E0] | min distance [m] | "
          "Newton iterations per step (mean, largest) | retries | steps guarded | "
          "integrator energy in contact steps [J] | wall [s]")
    print("--- | ---: | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---:")
    for r in results:
        done = "yes" if r["completed"] else f"no: step {r['steps'] + 1} ({r['error']})"
        growth = 100.0 * r["growth"] / abs(r["e0"])
        print(f"{r['shape']} | {r['speed']:g} | {r['integrator']} | {done} | {growth:+.2f} | {r['min_distance']:.2e} | "
              f"{r['mean_iterations']:.1f}, {r['max_iterations']} | {r['retries']} | {r['guarded']} | "
              f"{r['contact_integrator_energy']:+.4g} | {r['seconds']:.0f}")
    return 0 if all(r["completed"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
