#!/usr/bin/env python3
"""Writes the closed obstacle meshes of the moving-obstacle scenes into scenes/meshes/.

    wall.obj    a box [-0.5, 0.5]^3 (8 vertices, 12 triangles): scale it into a wall or a piston
    roller.obj  a closed cylinder of radius 0.5 and length 1 along z, centred on the origin, with
                SEGMENTS vertices per rim and a centre vertex per cap

Both are wound with outward normals (checked: the signed volume is positive), use only the
standard library, and come out the same on every run.

    python3 scripts/make_solid_obstacles.py [--segments 32] [--out-dir scenes/meshes]
"""
import argparse
import math
import pathlib


def box():
    vertices = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    # Vertex id = 4 ix + 2 iy + iz. Each face as a quad, counter-clockwise seen from outside.
    quads = [(0, 1, 3, 2), (4, 6, 7, 5),   # x = -0.5, x = +0.5
             (0, 4, 5, 1), (2, 3, 7, 6),   # y = -0.5, y = +0.5
             (0, 2, 6, 4), (1, 5, 7, 3)]   # z = -0.5, z = +0.5
    triangles = []
    for a, b, c, d in quads:
        triangles += [(a, b, c), (a, c, d)]
    return vertices, triangles


def cylinder(segments):
    vertices = []
    for z in (-0.5, 0.5):
        for s in range(segments):
            phi = 2.0 * math.pi * s / segments
            vertices.append((0.5 * math.cos(phi), 0.5 * math.sin(phi), z))
    back, front = len(vertices), len(vertices) + 1
    vertices += [(0.0, 0.0, -0.5), (0.0, 0.0, 0.5)]
    triangles = []
    for s in range(segments):
        t = (s + 1) % segments
        a, b, c, d = s, t, segments + t, segments + s  # side quad, outward
        triangles += [(a, b, c), (a, c, d)]
        triangles.append((back, b, a))    # cap at z = -0.5, normal -z
        triangles.append((front, d, c))   # cap at z = +0.5, normal +z
    return vertices, triangles


def signed_volume(vertices, triangles):
    total = 0.0
    for i, j, k in triangles:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = vertices[i], vertices[j], vertices[k]
        total += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6.0
    return total


def write_obj(path, title, vertices, triangles):
    if signed_volume(vertices, triangles) <= 0.0:
        raise SystemExit(f"{path}: triangles are not wound outward")
    lines = [f"# {title}", "# written by scripts/make_solid_obstacles.py"]
    lines += [f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in vertices]
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in triangles]
    path.write_text("\n".join(lines) + "\n")
    print(f"{path}: {len(vertices)} vertices, {len(triangles)} triangles")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, default=32)
    parser.add_argument("--out-dir", default="scenes/meshes")
    args = parser.parse_args()
    out = pathlib.Path(args.out_dir)
    write_obj(out / "wall.obj", "unit box [-0.5, 0.5]^3", *box())
    write_obj(out / "roller.obj", f"closed cylinder, radius 0.5, length 1 along z, {args.segments} segments",
              *cylinder(args.segments))


if __name__ == "__main__":
    main()
