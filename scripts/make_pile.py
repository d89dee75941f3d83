#!/usr/bin/env python3
"""Writes a stress scene: N bodies of mixed shapes falling into a box made of five planes.

Shapes, in turn: a `box` body (0.1 m, 2 x 2 x 2 cells, 48 tets), the IPC torus (0.12 m, 491
tets), the IPC cube (0.08 m, 6 tets) and the IPC pyramid (0.06 x 0.12 x 0.06 m, 3 tets), about
137 tets per body on average. They start on a square grid of columns, layer above layer,
0.16 m apart, each turned by a pseudo-random rotation (the same on every run for the same N;
drawn again where it could bring the body within 2 mm of a neighbour, as two boxes turned corner
to corner would be: see apart()), and fall under gravity into a container whose floor is at
y = 0 and whose walls leave 0.1 m around the grid. Neo-Hookean rubber (E 1e6), implicit Euler,
dt 0.01, contact with friction 0.3.

    python3 scripts/make_pile.py 1000                       # scenes/stress/pile_1000.json
    python3 scripts/make_pile.py 10000 --steps 20 --out /tmp/pile_10000.json
    python3 scripts/make_pile.py 1000 --affine --integrator default --steps 300 --friction-iterations 1
                                                            # pile_1000_affine
    python3 scripts/make_pile.py 100 --affine --out /tmp/pile_100_affine.json
    python3 scripts/make_pile.py 100 --youngs 1e9 --out /tmp/pile_100_e1e9.json
    python3 scripts/make_pile.py 10000 --layers 6 --affine --integrator default --steps 300 \
        --friction-iterations 1 --out scenes/stress/pile_10000w_affine.json   # ten pile_1000s wide

    python3 scripts/make_pile.py 1000 --affine --block 0.003 --integrator default   # block_1000_affine

`--block GAP` packs instead: 0.1 m boxes (one cell each way, 6 tets), GAP metres apart in a
block of columns x layers x rows, unrotated, 0.05 m above the floor, so that the block lands as
one (the hardest shape for contact counts). `--affine [KAPPA]` makes every body affine (material
"stone", density 1000, orthogonality stiffness KAPPA Pa, or the engine's default); `--youngs` sets
the rubber's Young's modulus; `--integrator` names the time integrator (`default`: leave the key
out, the engine's default); `--layers L` spreads the pile over as many columns as L layers need
(a wide, shallow pile: `pile_1000` has 6 layers, 10,000 bodies by default 13);
`--friction-iterations` sets `contact.friction_iterations` (1: friction lagged once a step, the
IPC paper's code's own default; the engine's default is "converged").

Mesh paths are written relative to the output file, so keep it in scenes/stress/ or pass --out
inside scenes/; the meshes are scenes/meshes/torus.msh, cube.msh and pyramid.msh.
"""
import argparse
import json
import math
import os
import pathlib

SPACING = 0.16  # [m] between body centres, every direction
# [m] the least gap between neighbouring bodies' turned shapes at the start (IPC needs one; two
# boxes of 0.1 m have corners 0.087 m from their centres, so two turned corner to corner would
# overlap at this spacing: such a body takes another rotation, see apart()).
MARGIN = 2e-3

SHAPES = [
    {"box": {"size": [0.1, 0.1, 0.1], "cells": [2, 2, 2]}},
    {"mesh": "torus.msh", "scale": 0.12},
    {"mesh": "cube.msh", "scale": 0.08, "centre": [0.5, 0.5, 0.5]},
    {"mesh": "pyramid.msh", "scale": 0.06, "centre": [0.5, 1.0, 0.5]},
]


def rotation(i):
    """Three angles in degrees from a small linear congruential generator seeded by i."""
    state = (i * 2654435761 + 12345) % 2**32
    angles = []
    for _ in range(3):
        state = (1664525 * state + 1013904223) % 2**32
        angles.append(round(360.0 * state / 2**32, 3))
    return angles


def mesh_nodes(path):
    """The node coordinates of a Gmsh 4.1 ASCII mesh."""
    lines = pathlib.Path(path).read_text().split("\n")
    at = lines.index("$Nodes") + 1
    blocks = int(lines[at].split()[0])
    at += 1
    nodes = []
    for _ in range(blocks):
        count = int(lines[at].split()[3])
        at += 1 + count  # the block's header, then its node tags
        nodes += [[float(c) for c in line.split()[:3]] for line in lines[at:at + count]]
        at += count
    return nodes


def shape_points(meshes):
    """Each shape's vertices about the point it turns about (the body's centre on the grid)."""
    points = []
    for shape in SHAPES:
        if "box" in shape:
            h = [0.5 * e for e in shape["box"]["size"]]
            signs = (-1, 1)
            points.append([[sx * h[0], sy * h[1], sz * h[2]] for sx in signs for sy in signs for sz in signs])
        else:
            centre = shape.get("centre", [0.0, 0.0, 0.0])
            points.append([[(c - o) * shape["scale"] for c, o in zip(node, centre)]
                           for node in mesh_nodes(meshes / shape["mesh"])])
    return points


def sphere_directions(count):
    """`count` unit vectors spread evenly over the sphere (a Fibonacci spiral from +y to -y)."""
    golden = math.pi * (3.0 - math.sqrt(5.0))
    directions = []
    for k in range(count):
        y = 1.0 - 2.0 * (k + 0.5) / count
        r = math.sqrt(1.0 - y * y)
        directions.append([r * math.cos(golden * k), y, r * math.sin(golden * k)])
    return directions


# The normals apart() looks for a plane between two neighbours along, after the grid axis.
DIRECTIONS = sphere_directions(256)


def apart(points_a, angles_a, points_b, angles_b, axis):
    """Whether two shapes turned by their angles, centred SPACING apart along grid axis `axis` (b
    after a), are MARGIN apart at least: some plane between them leaves that gap (each shape's
    reach towards the other along the plane's normal n, against the centres' SPACING n[axis]).
    A plane between two shapes' convex hulls lies between the shapes too, so this holds for the
    torus as well; it is sufficient, not necessary (only the directions tried count)."""
    a = [rotate(p, angles_a) for p in points_a]
    b = [rotate(p, angles_b) for p in points_b]
    unit = [1.0 if k == axis else 0.0 for k in range(3)]
    for n in [unit] + DIRECTIONS:
        if n[axis] <= 0.0:
            continue
        reach_a = max(sum(p[k] * n[k] for k in range(3)) for p in a)
        reach_b = max(-sum(p[k] * n[k] for k in range(3)) for p in b)
        if SPACING * n[axis] - reach_a - reach_b >= MARGIN:
            return True
    return False


def pile(count, steps, mesh_dir, affine=False, stiffness=None, youngs=1e6, integrator="implicit_euler",
         layers=None, points=None):
    if layers is None:
        columns = max(2, math.ceil(1.3 * count ** (1.0 / 3.0)))
    else:  # as many columns a side as `layers` layers need
        columns = max(2, math.ceil(math.sqrt(count / layers)))
    half = 0.5 * columns * SPACING + 0.1
    material = "stone" if affine else "rubber"
    radius = [max(math.sqrt(sum(c * c for c in p)) for p in shape) for shape in points] if points else None
    angles = []
    bodies = []
    for i in range(count):
        layer, cell = divmod(i, columns * columns)
        row, col = divmod(cell, columns)
        centre = [(col + 0.5) * SPACING - 0.5 * columns * SPACING, 0.1 + layer * SPACING,
                  (row + 0.5) * SPACING - 0.5 * columns * SPACING]
        kind = i % len(SHAPES)
        shape = dict(SHAPES[kind])
        # The neighbours before it on the grid (x, then z, then y), each SPACING away along an
        # axis; a rotation that could bring it within MARGIN of one is drawn again.
        neighbours = [(j, axis) for j, axis, on in ((i - 1, 0, col > 0), (i - columns, 2, row > 0),
                                                    (i - columns * columns, 1, layer > 0)) if on]
        turn = rotation(i)
        for draw in range(1, 1000):
            if not points or all(radius[kind] + radius[j % len(SHAPES)] <= SPACING - MARGIN or
                                 apart(points[j % len(SHAPES)], angles[j], points[kind], turn, axis)
                                 for j, axis in neighbours):
                break
            turn = rotation(i + draw * 1000003)
        else:
            raise SystemExit(f"body {i}: no rotation keeps it {MARGIN} m from its neighbours")
        angles.append(turn)
        body = {}
        if "box" in shape:
            body["box"] = shape["box"]
            translate = centre
        else:
            # A mesh turns about its own origin: to turn it about its centre instead, the
            # translation takes the rotated offset from the centre to the origin.
            body["mesh"] = mesh_dir + shape["mesh"]
            body["scale"] = shape["scale"]
            offset = [-c * shape["scale"] for c in shape.get("centre", [0.0, 0.0, 0.0])]
            translate = [c + o for c, o in zip(centre, rotate(offset, turn))]
        body["material"] = material
        body["rotate_deg"] = turn
        body["translate"] = [round(t, 9) for t in translate]
        bodies.append(body)
    time = {"dt": 0.01, "steps": steps}
    if integrator != "default":
        time["integrator"] = integrator
    return {
        "name": f"pile_{count}_affine" if affine else f"pile_{count}",
        "gravity": [0, -9.81, 0],
        "time": time,
        "solver": {"tolerance": 1e-3, "max_iterations": 200},
        "contact": {"dhat": 1e-3, "friction": 0.3},
        "materials": {material: material_of(affine, stiffness, youngs)},
        "bodies": bodies,
        "obstacles": container(half),
        "output": {"every": 10, "formats": ["vtu", "obj", "bodies"] if affine else ["vtu", "obj"]},
    }


def block(count, steps, gap, affine=False, stiffness=None, youngs=1e6, integrator="implicit_euler"):
    side = max(1, math.ceil(count ** (1.0 / 3.0)))
    size = 0.1
    pitch = size + gap
    half = 0.5 * side * pitch + 0.1
    material = "stone" if affine else "rubber"
    bodies = []
    for i in range(count):
        layer, cell = divmod(i, side * side)
        row, col = divmod(cell, side)
        centre = [(col + 0.5) * pitch - 0.5 * side * pitch, 0.05 + 0.5 * size + layer * pitch,
                  (row + 0.5) * pitch - 0.5 * side * pitch]
        bodies.append({"box": {"size": [size, size, size], "cells": [1, 1, 1]}, "material": material,
                       "translate": [round(c, 9) for c in centre]})
    scene = pile(1, steps, "", affine, stiffness, youngs, integrator)
    scene["name"] = f"block_{count}_affine" if affine else f"block_{count}"
    scene["bodies"] = bodies
    scene["obstacles"] = container(half)
    return scene


def container(half):
    """The floor at y = 0 and four walls at x, z = -half and +half, as obstacle planes."""
    walls = [([0, 0, 0], [0, 1, 0]), ([-half, 0, 0], [1, 0, 0]), ([half, 0, 0], [-1, 0, 0]),
             ([0, 0, -half], [0, 0, 1]), ([0, 0, half], [0, 0, -1])]
    return [{"plane": {"point": p, "normal": n}} for p, n in walls]


def material_of(affine, stiffness, youngs):
    if affine:
        stone = {"model": "affine", "density": 1000}
        if stiffness is not None:
            stone["stiffness"] = stiffness
        return stone
    return {"model": "neohookean", "youngs": youngs, "poisson": 0.4, "density": 1000}


def rotate(v, degrees):
    """v rotated about x, then y, then z (the scene's rotate_deg convention)."""
    x, y, z = v
    ax, ay, az = (math.radians(d) for d in degrees)
    y, z = y * math.cos(ax) - z * math.sin(ax), y * math.sin(ax) + z * math.cos(ax)
    x, z = x * math.cos(ay) + z * math.sin(ay), -x * math.sin(ay) + z * math.cos(ay)
    x, y = x * math.cos(az) - y * math.sin(az), x * math.sin(az) + y * math.cos(az)
    return [x, y, z]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("count", type=int, help="number of bodies (1 to 100000)")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--out", help="default: scenes/stress/pile_COUNT.json (pile_COUNT_affine.json, block_...)")
    parser.add_argument("--affine", nargs="?", const=-1.0, type=float, metavar="KAPPA",
                        help="affine bodies, with this orthogonality stiffness [Pa] if given")
    parser.add_argument("--youngs", type=float, default=1e6, help="the rubber's Young's modulus [Pa]")
    parser.add_argument("--integrator", default="implicit_euler", help="time.integrator ('default': none)")
    parser.add_argument("--friction-iterations", metavar="K",
                        help="contact.friction_iterations (a count, or 'converged'; default: the engine's)")
    parser.add_argument("--layers", type=int, metavar="L",
                        help="a pile L layers high (default: about 1.3 N^(1/3) columns a side, so taller with N)")
    parser.add_argument("--block", type=float, metavar="GAP",
                        help="boxes packed GAP metres apart in one block instead of a pile")
    args = parser.parse_args()
    if not 1 <= args.count <= 100000:
        raise SystemExit(f"count: expected 1 to 100000, got {args.count}")
    if args.layers is not None and not 1 <= args.layers <= args.count:
        raise SystemExit(f"--layers: expected 1 to {args.count} (the count), got {args.layers}")
    if args.block is not None and not args.block > 0.0:
        raise SystemExit(f"--block: expected a gap > 0 m, got {args.block}")
    root = pathlib.Path(__file__).resolve().parent.parent
    affine = args.affine is not None
    kind = "block" if args.block is not None else "pile"
    name = f"{kind}_{args.count}_affine" if affine else f"{kind}_{args.count}"
    out = pathlib.Path(args.out) if args.out else root / "scenes" / "stress" / f"{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    mesh_dir = os.path.relpath(root / "scenes" / "meshes", out.parent.resolve()) + "/"
    stiffness = args.affine if affine and args.affine > 0 else None
    if args.block is not None:
        scene = block(args.count, args.steps, args.block, affine, stiffness, args.youngs, args.integrator)
    else:
        scene = pile(args.count, args.steps, mesh_dir, affine, stiffness, args.youngs, args.integrator, args.layers,
                     shape_points(root / "scenes" / "meshes"))
    if args.friction_iterations is not None:
        k = args.friction_iterations
        scene["contact"]["friction_iterations"] = k if k == "converged" else int(k)
    out.write_text(json.dumps(scene, indent=1) + "\n")
    print(f"{out}: {args.count} bodies")


if __name__ == "__main__":
    main()
