// Is a triangle surface the boundary of a solid? The gate between a surface file and
// tetrahedralisation (issue 21).
//
// A tet mesher fills the inside of a surface, so the surface must have an inside: closed, a
// 2-manifold, consistently wound with normals outward, and not touching itself. A surface that
// fails any of these makes the mesher fail obscurely or, worse, produce a body with the wrong
// volume; checking first lets the run stop with one line that names the problem and where it is.
//
// checked_closed_surface drops the vertices no triangle uses (keeping the order of the others;
// OBJ files often carry them), then refuses the surface, with MeshError of one line
//   "<name>: <what>, <first bad element>",
// when it is, checks in this order:
//   1. empty (no triangle);
//   2. degenerate: a zero-area triangle (relative area <= kDegenerateTriangleRelativeArea,
//      obj_reader.hpp), a repeated vertex included;
//   3. duplicate triangles: two triangles on the same three vertices, in any order;
//   4. not closed: an edge used by one triangle only;
//   5. not manifold: an edge used by more than two triangles, or a vertex whose triangles form
//      more than one fan (two surfaces touching at a point);
//   6. not consistently oriented: two triangles traversing a shared edge in the same direction;
//   7. self-intersecting: two triangles that share no vertex and touch, or share exactly one
//      vertex and touch elsewhere too (self_intersection.hpp; the exact tests make touching
//      count, with no tolerance);
//   8. inverted: an enclosed volume <= 0, normals pointing inward.
// Within a check the first failure in triangle order is reported (the first triangle, then its
// first edge or corner), so the message is the same on every run. Vertices and triangles are
// named by their 1-based position in the input, which is the file's order: OBJ's own numbering,
// PLY's index + 1, STL's order of first occurrence; triangles count after polygons are split.
// The volume test is on the whole surface: a closed component wound inward inside another is a
// cavity and passes, and so does one beside a larger outward one (a per-component test would
// need to know which components nest).
#pragma once

#include <string_view>

#include "engine/mesh/surface_reader.hpp"

namespace nexdyn {

// The cleaned surface, or MeshError as above. Also MeshError for arrays that are not a surface
// at all: sizes not multiples of 3, ids out of range, non-finite positions.
TriangleSurface checked_closed_surface(TriangleSurface surface, std::string_view name);

// Volume enclosed by the surface [m^3], by the divergence theorem: the sum over triangles of
// det[a, b, c] / 6, in triangle order, with positions taken relative to the first triangle's first
// vertex (the result of a closed surface does not depend on the origin, and a nearby one keeps
// large coordinates from cancelling). Positive when a closed surface's normals point out.
double enclosed_volume(const TriangleSurface& surface);

}  // namespace nexdyn
