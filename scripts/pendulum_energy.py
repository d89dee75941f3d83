#!/usr/bin/env python3
"""Newmark against implicit Euler on the double pendulum (seed 000, issue 4).

Runs scenes/double_pendulum.json with both integrators at the same dt, prints the total energy
and the largest joint violation once per simulated second as a table, and draws the total
energy over time into an SVG plot (standard library only: no plotting package needed).

    python3 scripts/pendulum_energy.py                 # uses ./build/nexdyn, writes out/pendulum/
    python3 scripts/pendulum_energy.py --nexdyn /tmp/build/nexdyn --out /tmp/pendulum
"""
import argparse
import csv
import pathlib
import subprocess
import sys

SCHEMES = [("newmark", "#1f77b4"), ("implicit_euler", "#d62728")]


def run(nexdyn, scene, scheme, out):
    folder = out / scheme
    subprocess.run([nexdyn, "run", str(scene), "--integrator", scheme, "--quiet", "--out", str(folder)],
                   check=True)
    with open(folder / "stats.csv") as f:
        rows = list(csv.DictReader(f))
    return [(float(r["time"]), float(r["total_energy"]), float(r["kinetic_energy"]),
             float(r["joint_violation"])) for r in rows]


def table(series):
    print("time [s] | " + " | ".join(f"{s}: total energy [J], max violation [m]" for s, _ in SCHEMES))
    print("--- | " + " | ".join("---" for _ in SCHEMES))
    runs = [series[s] for s, _ in SCHEMES]
    steps_per_second = round(1.0 / (runs[0][1][0] - runs[0][0][0]))
    for end in range(steps_per_second - 1, len(runs[0]), steps_per_second):
        cells = []
        for rows in runs:
            worst = max(r[3] for r in rows[end + 1 - steps_per_second:end + 1])
            cells.append(f"{rows[end][1]:+.4f}, {worst:.1e}")
        print(f"{runs[0][end][0]:.0f} | " + " | ".join(cells))
    for (scheme, _), rows in zip(SCHEMES, runs):
        peak = max(r[2] for r in rows)
        drift = max(abs(r[1] - rows[0][1]) for r in rows)
        print(f"{scheme}: largest |E(t) - E(0)| = {drift:.4g} J = {100 * drift / peak:.3g}% of the "
              f"peak kinetic energy {peak:.4g} J")


def svg(series, path):
    width, height, margin = 800, 400, 60
    points = [p for s, _ in SCHEMES for p in series[s]]
    t_max = max(p[0] for p in points)
    e_lo, e_hi = min(p[1] for p in points), max(p[1] for p in points)
    e_lo, e_hi = e_lo - 0.05 * (e_hi - e_lo + 1e-12), e_hi + 0.05 * (e_hi - e_lo + 1e-12)

    def xy(t, e):
        return (margin + (width - 2 * margin) * t / t_max,
                height - margin - (height - 2 * margin) * (e - e_lo) / (e_hi - e_lo))

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="12">',
           f'<rect width="{width}" height="{height}" fill="white"/>',
           f'<line x1="{margin}" y1="{height - margin}" x2="{width - margin}" y2="{height - margin}" stroke="black"/>',
           f'<line x1="{margin}" y1="{margin}" x2="{margin}" y2="{height - margin}" stroke="black"/>',
           f'<text x="{width / 2}" y="{height - 20}" text-anchor="middle">time [s] (0 to {t_max:g})</text>',
           f'<text x="15" y="{height / 2}" transform="rotate(-90 15 {height / 2})" text-anchor="middle">'
           f'total energy [J] ({e_lo:.3g} to {e_hi:.3g})</text>']
    for k, (scheme, colour) in enumerate(SCHEMES):
        line = " ".join(f"{x:.1f},{y:.1f}" for x, y in (xy(t, e) for t, e, _, _ in series[scheme]))
        out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="{line}"/>')
        out.append(f'<text x="{width - margin - 150}" y="{margin + 18 * k}" fill="{colour}">{scheme}</text>')
    out.append("</svg>")
    path.write_text("\n".join(out) + "\n")


def main():
    root = pathlib.Path(__file__).resolve().parent.parent
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nexdyn", default=str(root / "build" / "nexdyn"))
    parser.add_argument("--out", default=str(root / "out" / "pendulum"))
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    if not pathlib.Path(args.nexdyn).exists():
        sys.exit(f"{args.nexdyn}: not found; build first (./build.sh) or pass --nexdyn")
    series = {s: run(args.nexdyn, root / "scenes" / "double_pendulum.json", s, out) for s, _ in SCHEMES}
    table(series)
    svg(series, out / "energy.svg")
    print(f"plot: {out / 'energy.svg'}")


if __name__ == "__main__":
    main()
