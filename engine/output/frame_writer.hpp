// Frame files: VTU (VTK unstructured grid, binary appended data) per frame plus the ParaView
// series file scene.pvd, and OBJ surfaces on request (DESIGN.md section 6).
//
// Every file is written to "<name>.tmp" and renamed into place, so a reader never sees a
// half-written frame, even when the run is killed in the middle of a write.
#pragma once

#include "engine/atomic_file.hpp"
#include "engine/model.hpp"
#include "engine/mpm/particles.hpp"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace nexdyn {


// frames/frame_NNNNNN.<ext>
std::string frame_file_name(int64_t frame, const char* extension);

// VTU with points, tets, and point data "velocity" and "body".
std::string vtu_document(const Model& model, const std::vector<double>& x, const std::vector<double>& v);
// VTU point cloud of MPM particles: one vertex cell per particle, point data "velocity", "J"
// (det F), "von_mises" (the von Mises stress of the Cauchy stress J^-1 P F^T, Pa), "body" and
// "radius" (half the edge of a cube of the particle's volume, J V_p^0: what `nexdyn render` draws).
std::string vtu_particles_document(const Particles& particles, const std::vector<int32_t>& particle_body,
                                   const std::vector<Material>& materials);
// frames/bodies_NNNNNN.csv
std::string bodies_file_name(int64_t frame);
// The header of the bodies file and its document: one row per body of the scene's "bodies" (not
// the obstacles), in model order; `body` is the id the VTU frames' "body" data give its vertices.
// mass [kg], centre of mass [m] and its velocity [m/s] from the vertices' lumped masses; the
// twelve cells omega_* and a_ij, which affine bodies fill, are empty for tet bodies.
inline constexpr const char* kBodiesHeader =
    "body,kind,mass,com_x,com_y,com_z,vel_x,vel_y,vel_z,omega_x,omega_y,omega_z,a11,a12,a13,a21,a22,a23,a31,a32,a33";
std::string bodies_document(const Model& model, const std::vector<double>& x, const std::vector<double>& v);
// OBJ with every vertex (global numbering, 1-based in the file) and every surface triangle.
std::string obj_document(const Model& model, const std::vector<double>& x);
// ParaView collection of (time, relative file) pairs.
std::string pvd_document(const std::vector<std::pair<double, std::string>>& frames);

}  // namespace nexdyn
