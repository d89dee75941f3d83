// The engine's own box mesher: an axis-aligned box of nx x ny x nz hexahedral cells, each split
// into 6 tets, centred on the origin. Scene `box` bodies are built with it, and it gives tests and
// benchmarks meshes of any size without files.
//
// Split: the Kuhn (Freudenthal) triangulation. Every cell is cut into the 6 tets that run along
// its main diagonal from corner (0,0,0) to corner (1,1,1), one per order in which the path steps
// in x, y and z. Every cell face is then cut along the diagonal through its own lowest and
// highest corner, which is the same for the two cells sharing it, so the mesh is conforming
// (no hanging edges, no T-junctions) with the identical split in every cell. The price is a
// slight anisotropy along (1,1,1); the 5-tet split is more symmetric but must alternate
// between cells.
#pragma once

#include <Eigen/Core>
#include <array>

#include "engine/mesh/tet_mesh.hpp"

namespace nexdyn {

inline constexpr int kTetsPerBoxCell = 6;

// size: edge lengths (metres, each > 0 and finite); cells: cells per axis (each >= 1).
// Vertex (i, j, k) has id i + (nx+1) * (j + (ny+1) * k) and position size * ((i,j,k)/n - 1/2).
// Tets are positively oriented; cell (i, j, k) owns tets [6 c, 6 c + 6) with
// c = i + nx * (j + ny * k). Throws std::invalid_argument on bad input or when the mesh would
// not fit in 32-bit ids.
TetMesh make_box_mesh(const Eigen::Vector3d& size, const std::array<int, 3>& cells);

}  // namespace nexdyn
