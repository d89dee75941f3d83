#!/usr/bin/env python3
"""Writes the surface-file corpus of tests/engine/mesh/test_surface_input.cpp (issue 21).

Into tests/data/meshes/surfaces/:
  good: one closed box in every format the surface reader takes, all of which must read to the
        same surface (same vertex order, same triangles, volume 0.125):
          cube.obj (quads), cube_ascii.stl, cube_binary.stl, cube_binary_solid_header.stl
          (a binary STL whose 80-byte header starts with "solid"), cube_ascii.ply (quads, vertex
          normals), cube_binary_le.ply (double coordinates, colours, a scalar before the face
          list, an extra element after the faces), cube_binary_be.ply (float coordinates,
          triangles, a ushort list count);
  refused by the closed-surface check, one problem each:
          open_box.obj, nonmanifold_edge.obj, nonmanifold_vertex.obj, flipped_triangle.obj,
          self_intersecting.obj, inverted.obj, degenerate_triangle.ply;
  refused by the readers: truncated_binary.stl, bad_header.ply.
Into tests/data/fuzz/fuzz_stl/ and fuzz_ply/: a tet in each encoding, the fuzzers' small seeds.

The box is [1, 1.5] x [2, 2.5] x [3, 3.5]: every coordinate is exact in float, so the binary STL
and the float PLY hold the same numbers as the text files. The vertex order of the OBJ and PLY
files is the order in which the STL's welding meets the corners (first occurrence in the
fan-triangulated faces), which is what makes all seven read to identical arrays.

    python3 scripts/make_test_surfaces.py     # rewrites the files; standard library only
"""
import pathlib
import struct

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests" / "data" / "meshes" / "surfaces"


def box_quads(lo, hi):
    """The 6 faces of an axis-aligned box as quads of corner points, wound outward."""
    corner = lambda i, j, k: (hi[0] if i else lo[0], hi[1] if j else lo[1], hi[2] if k else lo[2])
    quads = []
    for axis in range(3):
        for side in (0, 1):
            # The face's corners in a cycle of the two other axes, (0,0) (1,0) (1,1) (0,1).
            u, v = (axis + 1) % 3, (axis + 2) % 3
            cycle = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                index = [0, 0, 0]
                index[axis], index[u], index[v] = side, a, b
                cycle.append(corner(*index))
            # (u, v, axis) is right-handed, so this cycle's normal is +axis: reverse it for side 0.
            quads.append(cycle if side else cycle[::-1])
    return quads


def fan(polygon):
    return [(polygon[0], polygon[k], polygon[k + 1]) for k in range(1, len(polygon) - 1)]


def index_polygons(polygons):
    """Points numbered by first occurrence in the fan triangles; polygons as index lists."""
    ids, points = {}, []
    for polygon in polygons:
        for triangle in fan(polygon):
            for p in triangle:
                if p not in ids:
                    ids[p] = len(points)
                    points.append(p)
    return points, [[ids[p] for p in polygon] for polygon in polygons]


def number(x):
    return repr(float(x)).rstrip("0").rstrip(".") if float(x) != int(x) else str(int(x))


def obj_text(points, polygons, comment):
    lines = [f"# {comment}"] + ["v " + " ".join(number(c) for c in p) for p in points]
    lines += ["f " + " ".join(str(i + 1) for i in poly) for poly in polygons]
    return "\n".join(lines) + "\n"


def normal(t):
    a, b, c = t
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    length = sum(x * x for x in n) ** 0.5
    return [x / length for x in n]


def ascii_stl(triangles, name):
    lines = [f"solid {name}"]
    for t in triangles:
        lines.append("  facet normal " + " ".join(number(x) for x in normal(t)))
        lines.append("    outer loop")
        lines += ["      vertex " + " ".join(number(c) for c in p) for p in t]
        lines += ["    endloop", "  endfacet"]
    lines.append(f"endsolid {name}")
    return ("\n".join(lines) + "\n").encode()


def binary_stl(triangles, header):
    data = header.encode().ljust(80, b"\0")[:80] + struct.pack("<I", len(triangles))
    for t in triangles:
        data += struct.pack("<12fH", *normal(t), *(c for p in t for c in p), 0)
    return data


QUADS = box_quads((1.0, 2.0, 3.0), (1.5, 2.5, 3.5))
POINTS, POLYGONS = index_polygons(QUADS)
TRIANGLES = [t for q in QUADS for t in fan(q)]
TRIANGLE_IDS = [t for poly in POLYGONS for t in fan(poly)]


def write(name, data):
    (OUT / name).write_bytes(data if isinstance(data, bytes) else data.encode())


def good_files():
    write("cube.obj", obj_text(POINTS, POLYGONS, "closed box [1,1.5]x[2,2.5]x[3,3.5], quads wound outward"))
    write("cube_ascii.stl", ascii_stl(TRIANGLES, "cube"))
    write("cube_binary.stl", binary_stl(TRIANGLES, "binary STL: box [1,1.5]x[2,2.5]x[3,3.5]"))
    write("cube_binary_solid_header.stl", binary_stl(TRIANGLES, "solid cube, binary all the same"))

    # ASCII PLY: float coordinates with vertex normals, quads with a uchar count.
    header = ["ply", "format ascii 1.0", "comment closed box, quads wound outward",
              f"element vertex {len(POINTS)}", "property float x", "property float y", "property float z",
              "property float nx", "property float ny", "property float nz",
              f"element face {len(POLYGONS)}", "property list uchar int vertex_indices", "end_header"]
    body = [" ".join(number(c) for c in p) + " 0 0 1" for p in POINTS]
    body += [f"{len(poly)} " + " ".join(map(str, poly)) for poly in POLYGONS]
    write("cube_ascii.ply", "\n".join(header + body) + "\n")

    # Little-endian PLY: double coordinates among colours, a scalar before the face list, and an
    # element the reader must skip after the faces.
    header = ["ply", "format binary_little_endian 1.0", "comment closed box, quads wound outward",
              f"element vertex {len(POINTS)}", "property uchar red", "property double x", "property double y",
              "property double z", "property uchar green", "property uchar blue",
              f"element face {len(POLYGONS)}", "property int material",
              "property list uchar uint vertex_index",
              "element edge 2", "property int vertex1", "property int vertex2", "end_header"]
    data = ("\n".join(header) + "\n").encode()
    for p in POINTS:
        data += struct.pack("<B3dBB", 200, *p, 100, 50)
    for poly in POLYGONS:
        data += struct.pack(f"<iB{len(poly)}I", 7, len(poly), *poly)
    data += struct.pack("<4i", 0, 1, 1, 2)
    write("cube_binary_le.ply", data)

    # Big-endian PLY: float coordinates, triangles with a ushort count.
    header = ["ply", "format binary_big_endian 1.0", f"element vertex {len(POINTS)}", "property float x",
              "property float y", "property float z", f"element face {len(TRIANGLE_IDS)}",
              "property list ushort int vertex_indices", "end_header"]
    data = ("\n".join(header) + "\n").encode()
    for p in POINTS:
        data += struct.pack(">3f", *p)
    for t in TRIANGLE_IDS:
        data += struct.pack(">H3i", 3, *t)
    write("cube_binary_be.ply", data)


def triangle_obj(name, comment, points, triangles):
    write(name, obj_text(points, triangles, comment))


def refused_files():
    cube_points, cube_triangles = index_polygons([t for q in QUADS for t in fan(q)])

    # The top face (z = 3.5, its two triangles) missing.
    open_triangles = [t for t in cube_triangles if not all(cube_points[i][2] == 3.5 for i in t)]
    triangle_obj("open_box.obj", "box without its top face: not closed", cube_points, open_triangles)

    # Two unit cubes sharing the edge x = 1, y = 1: 4 triangles on that edge.
    quads = box_quads((0, 0, 0), (1, 1, 1)) + box_quads((1, 1, 0), (2, 2, 1))
    points, triangles = index_polygons([t for q in quads for t in fan(q)])
    triangle_obj("nonmanifold_edge.obj", "two cubes sharing an edge: not manifold", points, triangles)

    # Two tets touching at the origin, both wound outward.
    tet_a = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    tet_b = [(0, 0, 0), (-1, 0, 0), (0, 0, -1), (0, -1, 0)]
    faces = lambda t: [(t[0], t[2], t[1]), (t[0], t[1], t[3]), (t[0], t[3], t[2]), (t[1], t[2], t[3])]
    points, triangles = index_polygons(faces(tet_a) + faces(tet_b))
    triangle_obj("nonmanifold_vertex.obj", "two tets touching at a vertex: not manifold", points, triangles)

    # One triangle (the 7th) wound the other way.
    flipped = [list(t) for t in cube_triangles]
    flipped[6] = flipped[6][::-1]
    triangle_obj("flipped_triangle.obj", "box with triangle 7 reversed: not consistently oriented",
                 cube_points, flipped)

    # Two closed boxes that pass through each other, in one file with their own vertices.
    quads_a = box_quads((0, 0, 0), (2, 2, 2))
    quads_b = box_quads((1, 1, 1), (3, 3, 3))
    points_a, triangles_a = index_polygons([t for q in quads_a for t in fan(q)])
    points_b, triangles_b = index_polygons([t for q in quads_b for t in fan(q)])
    offset = len(points_a)
    triangle_obj("self_intersecting.obj", "two interpenetrating boxes: self-intersecting",
                 points_a + points_b, triangles_a + [[i + offset for i in t] for t in triangles_b])

    # Every triangle wound inward.
    triangle_obj("inverted.obj", "box wound inward: inverted", cube_points, [t[::-1] for t in cube_triangles])

    # The box plus a 13th triangle of zero area: corners 1 and 2 and the midpoint of their edge.
    a, b = cube_points[0], cube_points[1]
    mid = tuple((a[k] + b[k]) / 2 for k in range(3))
    points = cube_points + [mid]
    header = ["ply", "format ascii 1.0", "comment box plus one zero-area triangle",
              f"element vertex {len(points)}", "property double x", "property double y", "property double z",
              f"element face {len(cube_triangles) + 1}", "property list uchar int vertex_indices",
              "end_header"]
    body = [" ".join(number(c) for c in p) for p in points]
    body += ["3 " + " ".join(map(str, t)) for t in cube_triangles + [[0, 1, len(points) - 1]]]
    write("degenerate_triangle.ply", "\n".join(header + body) + "\n")

    # Malformed: a binary STL (header starting with "solid") cut 10 bytes short; a PLY header
    # with a misspelt type.
    write("truncated_binary.stl", binary_stl(TRIANGLES, "solid cube, binary, truncated")[:-10])
    text = (OUT / "cube_ascii.ply").read_text().replace("property float y", "property floot y")
    write("bad_header.ply", text)


def fuzz_seeds():
    """A positively oriented unit tet in every encoding, written where scripts/fuzz.sh seeds from."""
    fuzz = OUT.parent.parent / "fuzz"
    corners = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    triangles = [tuple(corners[i] for i in f) for f in faces]
    (fuzz / "fuzz_stl").mkdir(exist_ok=True)
    (fuzz / "fuzz_stl" / "tet_ascii.stl").write_bytes(ascii_stl(triangles, "tet"))
    (fuzz / "fuzz_stl" / "tet_binary.stl").write_bytes(binary_stl(triangles, "solid tet, binary"))
    (fuzz / "fuzz_ply").mkdir(exist_ok=True)
    header = ["ply", "format ascii 1.0", "element vertex 4", "property float x", "property float y",
              "property float z", "element face 4", "property list uchar int vertex_indices", "end_header"]
    body = [" ".join(number(c) for c in p) for p in corners] + ["3 " + " ".join(map(str, f)) for f in faces]
    (fuzz / "fuzz_ply" / "tet_ascii.ply").write_text("\n".join(header + body) + "\n")
    for order, name in (("<", "binary_little_endian"), (">", "binary_big_endian")):
        header[1] = f"format {name} 1.0"
        data = ("\n".join(header) + "\n").encode()
        data += b"".join(struct.pack(order + "3f", *p) for p in corners)
        data += b"".join(struct.pack(order + "B3i", 3, *f) for f in faces)
        (fuzz / "fuzz_ply" / f"tet_{name}.ply").write_bytes(data)


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    good_files()
    refused_files()
    fuzz_seeds()
