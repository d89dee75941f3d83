#!/usr/bin/env python3
"""Writes a twisting-mat scene at any resolution: the resolution series of issue 5.

The mat is the IPC paper's twisting mat (scenes/mat40x40_twist.json) built from a `box` body
instead of a mesh file: 1 m x 1 m x 8 mm, N x N cells and one cell through the thickness, 6 tets
per cell, so (N + 1)^2 x 2 vertices and 6 N^2 tets. Its two ends (x = -0.5 and x = 0.5) turn in
opposite directions about the x axis at 0.2 turns per second, as in the IPC scene; neo-Hookean,
E 2e4, implicit Euler, dt 0.04, contact on (the mat folds onto itself after about 1.5 s).

    python3 scripts/make_mat.py 40                          # scenes/stress/mat_40.json, ~10k DOFs
    python3 scripts/make_mat.py 128 --steps 3 --out /tmp/mat_128.json   # ~100k DOFs
    python3 scripts/make_mat.py 407 --steps 3 --out /tmp/mat_407.json   # ~1M DOFs

Standard library only.
"""
import argparse
import json
import math
import pathlib

TURN_RATE = 0.4 * math.pi  # [rad/s] of each end, in opposite directions


def scene(cells, steps):
    ends = []
    for x, sign in ((-0.5, 1.0), (0.5, -1.0)):
        ends.append({"box_min": [x - 0.01, -1, -1], "box_max": [x + 0.01, 1, 1],
                     "angular_velocity": sign * TURN_RATE, "axis": [1, 0, 0], "center": [0, 0, 0]})
    return {
        "name": f"mat_{cells}",
        "gravity": [0, 0, 0],
        "time": {"dt": 0.04, "steps": steps, "integrator": "implicit_euler"},
        "solver": {"tolerance": 1e-2, "max_iterations": 500},
        "contact": {},
        "materials": {"mat": {"model": "neohookean", "youngs": 2e4, "poisson": 0.4, "density": 1000}},
        "bodies": [{"box": {"size": [1.0, 1.0, 0.008], "cells": [cells, cells, 1]}, "material": "mat"}],
        "boundary": ends,
        "output": {"every": 5, "formats": ["obj"]},
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("cells", type=int, help="cells along each side of the mat (1..1000)")
    parser.add_argument("--steps", type=int, default=250, help="time steps (default 250: 10 s)")
    parser.add_argument("--out", type=pathlib.Path, help="default: scenes/stress/mat_<cells>.json")
    args = parser.parse_args()
    if not 1 <= args.cells <= 1000:
        parser.error(f"cells must be 1..1000, got {args.cells}")
    if args.steps < 1:
        parser.error(f"--steps must be >= 1, got {args.steps}")
    out = args.out or pathlib.Path(__file__).resolve().parent.parent / "scenes" / "stress" / f"mat_{args.cells}.json"
    out.write_text(json.dumps(scene(args.cells, args.steps), indent=1) + "\n")
    vertices = (args.cells + 1) ** 2 * 2
    print(f"{out}: {vertices} vertices, {3 * vertices} DOFs, {6 * args.cells ** 2} tets")


if __name__ == "__main__":
    main()
