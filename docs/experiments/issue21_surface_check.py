#!/usr/bin/env python3
"""An independent check of closed triangle surfaces (.obj), to confirm checked_closed_surface.

Issue 21: before the C++ surface check (engine/mesh/surface_check.cpp) was trusted with the
accepted/refused list of the shared triMeshes (tests/engine/mesh/test_surface_input.cpp), each
verdict was recomputed here by other means:
  - exact arithmetic throughout: every coordinate (a double, as the C++ reader parses it) is
    scaled to an integer by one common power of two, so all geometry is Python integers;
  - fans around a vertex by a breadth-first search over its triangles (C++: union-find on
    corners);
  - crossing triangles by the separating axis theorem (the two normals, the 9 edge-edge cross
    products and the 6 in-plane edge normals; C++: edge-against-triangle orientation tests);
  - triangles sharing one vertex v by their corners at v: they overlap beyond v iff the two wedges
    v + cone(p1 - v, p2 - v) and v + cone(q1 - v, q2 - v) meet beyond v (near v each triangle
    is its wedge, and the intersection is convex), i.e. iff some nonzero l >= 0 solves
    l1 a1 + l2 a2 - l3 b1 - l4 b2 = 0, decided by its circuits (minimal dependent column sets):
    a solution exists iff the kernel vector of some circuit has one sign;
  - the volume as an exact rational.
The checks, their order and "first in triangle order" follow surface_check.hpp, and the output
line is the C++ message's text after the file name, so the two can be compared word for word.

    python3 docs/experiments/issue21_surface_check.py FILE.obj ...   # standard library only
"""
import itertools
import math
import sys
from fractions import Fraction


def read_obj(path):
    positions, triangles = [], []
    for line in open(path, encoding="utf-8", errors="replace"):
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            positions.append(tuple(float(w) for w in words[1:4]))
        elif words[0] == "f":
            ids = []
            for corner in words[1:]:
                i = int(corner.split("/")[0])
                ids.append(i - 1 if i > 0 else len(positions) + i)
            triangles += [(ids[0], ids[k], ids[k + 1]) for k in range(1, len(ids) - 1)]
    return positions, triangles


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def integer_points(positions):
    """Every double as an integer times 2^-shift, one shift for all: exact integer geometry."""
    fractions = [tuple(Fraction(c) for c in p) for p in positions]
    denominator = max((c.denominator for p in fractions for c in p), default=1)
    return [tuple(int(c * denominator) for c in p) for p in fractions]


def separated(P, Q):
    """Closed triangles P, Q (integer points) are disjoint: some axis strictly separates them."""
    e = [sub(P[(k + 1) % 3], P[k]) for k in range(3)]
    f = [sub(Q[(k + 1) % 3], Q[k]) for k in range(3)]
    n, m = cross(e[0], e[1]), cross(f[0], f[1])
    axes = [n, m] + [cross(a, b) for a in e for b in f]
    axes += [cross(n, a) for a in e + f] + [cross(m, a) for a in e + f]
    for axis in axes:
        if axis == (0, 0, 0):
            continue
        p = [dot(axis, x) for x in P]
        q = [dot(axis, x) for x in Q]
        if max(p) < min(q) or max(q) < min(p):
            return True
    return False


def det3(a, b, c):
    return dot(a, cross(b, c))


def wedges_meet(v, p1, p2, q1, q2):
    """Wedges at v meet beyond v: a nonzero l >= 0 with l1 a1 + l2 a2 - l3 b1 - l4 b2 = 0."""
    a1, a2, b1, b2 = sub(p1, v), sub(p2, v), sub(q1, v), sub(q2, v)
    columns = [a1, a2, tuple(-x for x in b1), tuple(-x for x in b2)]
    parallel = lambda x, y: cross(x, y) == (0, 0, 0)
    one_sign = lambda values: all(x > 0 for x in values) or all(x < 0 for x in values)
    for i, j in itertools.combinations(range(4), 2):  # circuits of 2: parallel columns
        if parallel(columns[i], columns[j]) and dot(columns[i], columns[j]) < 0:
            return True
    for i, j, k in itertools.combinations(range(4), 3):  # circuits of 3: coplanar, no two parallel
        x, y, z = columns[i], columns[j], columns[k]
        if det3(x, y, z) != 0 or parallel(x, y) or parallel(y, z) or parallel(z, x):
            continue
        normal = cross(x, y)
        if one_sign([dot(cross(y, z), normal), dot(cross(z, x), normal), dot(cross(x, y), normal)]):
            return True
    # The circuit of all 4: any 3 independent; kernel entries are signed 3x3 determinants.
    minors = [det3(*[columns[c] for c in range(4) if c != skip]) for skip in range(4)]
    if all(m != 0 for m in minors) and one_sign([(-1) ** k * minors[k] for k in range(4)]):
        return True
    return False


def check(positions, triangles):
    """None when accepted, else the C++ message's text after "<name>: "."""
    ids = " (ids 1-based)"
    name = lambda i: str(i + 1)
    if not triangles:
        return "empty surface, no triangles"
    P = [tuple(p) for p in positions]
    for t, (a, b, c) in enumerate(triangles):
        area = math.dist((0, 0, 0), cross(sub(P[b], P[a]), sub(P[c], P[a]))) / 2
        longest = max(math.dist(P[a], P[b]), math.dist(P[b], P[c]), math.dist(P[c], P[a]))
        if len({a, b, c}) < 3 or area <= 1e-12 * longest ** 2:
            return (f"degenerate (zero-area) triangle, triangle {t + 1} of vertices "
                    f"{name(a)} {name(b)} {name(c)}{ids}")
    first_seen = {}
    for t, tri in enumerate(triangles):
        key = tuple(sorted(tri))
        if key in first_seen:
            o = first_seen[key]
            return (f"duplicate triangles, triangle {t + 1} repeats triangle {o + 1}, vertices "
                    + " ".join(name(v) for v in triangles[o]) + ids)
        first_seen[key] = t
    users = {}  # undirected edge -> [(triangle, from, to)] in triangle order
    for t, tri in enumerate(triangles):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            users.setdefault((min(a, b), max(a, b)), []).append((t, a, b))
    half_edges = sorted((t, k) for t, tri in enumerate(triangles) for k in range(3))
    for t, k in half_edges:
        a, b = triangles[t][k], triangles[t][(k + 1) % 3]
        if len(users[(min(a, b), max(a, b))]) == 1:
            return f"not closed, edge {name(a)}-{name(b)} is used by triangle {t + 1} only{ids}"
    for t, k in half_edges:
        a, b = triangles[t][k], triangles[t][(k + 1) % 3]
        u = users[(min(a, b), max(a, b))]
        if len(u) > 2 and u[0][0] == t:
            listed = ", ".join(str(x[0] + 1) for x in u[:6]) + (", ..." if len(u) > 6 else "")
            return (f"not manifold, edge {name(min(a, b))}-{name(max(a, b))} is shared by {len(u)} "
                    f"triangles: {listed}{ids}")
    around = {}
    for t, tri in enumerate(triangles):
        for v in tri:
            around.setdefault(v, []).append(t)
    fan_of = {}
    for v, tris in around.items():  # breadth-first search over v's triangles joined by edges at v
        fan, count = {}, 0
        for start in tris:
            if start in fan:
                continue
            fan[start], queue = count, [start]
            while queue:
                t = queue.pop()
                for w in triangles[t]:
                    if w == v:
                        continue
                    for other, _, _ in users[(min(v, w), max(v, w))]:
                        if other not in fan:
                            fan[other] = count
                            queue.append(other)
            count += 1
        fan_of[v] = (fan, count)
    for t, tri in enumerate(triangles):
        for v in tri:
            fan, count = fan_of[v]
            first = around[v][0]
            if fan[t] != fan[first]:
                return (f"not manifold, vertex {name(v)} joins {count} separate fans of triangles, "
                        f"e.g. triangles {first + 1} and {t + 1}{ids}")
    for t, k in half_edges:
        a, b = triangles[t][k], triangles[t][(k + 1) % 3]
        (t1, f1, _), (t2, f2, _) = users[(min(a, b), max(a, b))]
        if f1 == f2 and t1 == t:
            return (f"not consistently oriented, triangles {t1 + 1} and {t2 + 1} both traverse edge "
                    f"{name(a)}->{name(b)}{ids}")
    Z = integer_points(P)
    boxes = [(min(Z[v][0] for v in tri), max(Z[v][0] for v in tri)) for tri in triangles]
    order = sorted(range(len(triangles)), key=lambda t: boxes[t][0])
    hits = []
    for n, i in enumerate(order):
        for j in order[n + 1:]:
            if boxes[j][0] > boxes[i][1]:
                break
            s, t = min(i, j), max(i, j)
            shared = set(triangles[s]) & set(triangles[t])
            if len(shared) >= 2:
                continue
            S, T = [Z[v] for v in triangles[s]], [Z[v] for v in triangles[t]]
            if not shared:
                if not separated(S, T):
                    hits.append((s, t, ""))
                continue
            v = shared.pop()
            ks, kt = triangles[s].index(v), triangles[t].index(v)
            if wedges_meet(Z[v], S[(ks + 1) % 3], S[(ks + 2) % 3], T[(kt + 1) % 3], T[(kt + 2) % 3]):
                hits.append((s, t, name(v)))
    if hits:
        s, t, v = min(hits)
        how = f" overlap beyond their shared vertex {v}" if v else " intersect"
        return f"self-intersecting, triangles {s + 1} and {t + 1}{how}{ids}"
    volume = sum(Fraction(det3(*[tuple(Fraction(c) for c in P[v]) for v in tri])) for tri in triangles) / 6
    if volume <= 0:
        return f"inverted, enclosed volume {float(volume):.6g} m^3 <= 0: the normals point inward"
    return None


def main(paths):
    for path in paths:
        positions, triangles = read_obj(path)
        used = sorted({v for t in triangles for v in t})
        verdict = check(positions, triangles)
        if verdict is None:
            volume = sum(det3(*[positions[v] for v in tri]) for tri in triangles) / 6
            print(f"{path}: accepted, {len(used)} vertices, {len(triangles)} triangles, volume {volume:.6g}")
        else:
            print(f"{path}: refused: {verdict}")


if __name__ == "__main__":
    main(sys.argv[1:])
