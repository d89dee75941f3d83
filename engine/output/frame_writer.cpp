// VTU / PVD / OBJ writers (see frame_writer.hpp).
#include "engine/output/frame_writer.hpp"

#include "kernels/elasticity/elasticity.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace nexdyn {

std::string frame_file_name(int64_t frame, const char* extension) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "frame_%06lld.%s", static_cast<long long>(frame), extension);
  return buf;
}

std::string bodies_file_name(int64_t frame) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "bodies_%06lld.csv", static_cast<long long>(frame));
  return buf;
}

std::string bodies_document(const Model& model, const std::vector<double>& x, const std::vector<double>& v) {
  std::string text = std::string(kBodiesHeader) + "\n";
  char buf[512];
  std::vector<int32_t> affine_of_body(model.bodies.size(), -1);
  for (size_t k = 0; k < model.affine_bodies.size(); ++k) affine_of_body[model.affine_bodies[k].body] = int32_t(k);
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const BodyRange& body = model.bodies[b];
    if (body.obstacle) continue;
    if (affine_of_body[b] >= 0) {
      // p and its velocity; A = C R^T with C = [c_0 c_1 c_2] (Model::AffineBody), A' = C' R^T, and
      // omega the axial vector of the skew part of A' A^-1 (exactly omega for a rigid rotation).
      const AffineBody& affine = model.affine_bodies[affine_of_body[b]];
      const int64_t node = affine.node;
      Eigen::Matrix3d C, C_dot;
      for (int j = 0; j < 3; ++j) {
        C.col(j) = Eigen::Vector3d::Map(&x[3 * (node + 1 + j)]);
        C_dot.col(j) = Eigen::Vector3d::Map(&v[3 * (node + 1 + j)]);
      }
      const Eigen::Matrix3d A = C * affine.frame.transpose(), A_dot = C_dot * affine.frame.transpose();
      const Eigen::Matrix3d W = A_dot * A.inverse();
      const Eigen::Vector3d omega(0.5 * (W(2, 1) - W(1, 2)), 0.5 * (W(0, 2) - W(2, 0)), 0.5 * (W(1, 0) - W(0, 1)));
      const Eigen::Vector3d p = Eigen::Vector3d::Map(&x[3 * node]), p_dot = Eigen::Vector3d::Map(&v[3 * node]);
      int n = std::snprintf(buf, sizeof(buf), "%zu,affine,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g",
                            b, model.mass[node], p.x(), p.y(), p.z(), p_dot.x(), p_dot.y(), p_dot.z(), omega.x(),
                            omega.y(), omega.z());
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) n += std::snprintf(buf + n, sizeof(buf) - n, ",%.17g", A(r, c));
      text += std::string(buf) + "\n";
      continue;
    }
    double mass = 0.0;
    Eigen::Vector3d moment = Eigen::Vector3d::Zero(), momentum = Eigen::Vector3d::Zero();
    for (int32_t i = body.vertex_begin; i < body.vertex_begin + body.vertex_count; ++i) {
      mass += model.mass[i];
      moment += model.mass[i] * Eigen::Vector3d::Map(&x[3 * i]);
      momentum += model.mass[i] * Eigen::Vector3d::Map(&v[3 * i]);
    }
    const Eigen::Vector3d com = moment / mass, velocity = momentum / mass;
    std::snprintf(buf, sizeof(buf), "%zu,tets,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,,,,,,,,,,,,\n", b, mass,
                  com.x(), com.y(), com.z(), velocity.x(), velocity.y(), velocity.z());
    text += buf;
  }
  return text;
}

namespace {
// Appended raw binary data: each array is a UInt64 byte count followed by its bytes; a DataArray
// refers to it by its offset from the start of the data block (after the '_').
class AppendedData {
 public:
  template <typename T>
  int64_t add(const T* data, size_t count) {
    const int64_t offset = static_cast<int64_t>(bytes_.size());
    const uint64_t size = sizeof(T) * count;
    append(&size, sizeof(size));
    append(data, size);
    return offset;
  }
  const std::string& bytes() const { return bytes_; }

 private:
  void append(const void* p, size_t n) { bytes_.append(static_cast<const char*>(p), n); }
  std::string bytes_;
};

// One DataArray of a VTU file: where its bytes start in the appended block.
struct VtuArray {
  const char* type;
  const char* name;
  int components;
  int64_t offset;
};

// The XML of an unstructured-grid VTU whose arrays are all in `data`; `point_attributes` names
// the default vector (and scalar) of the point data.
std::string vtu_file(size_t num_points, size_t num_cells, const char* point_attributes,
                     std::initializer_list<VtuArray> point_data, VtuArray points,
                     std::initializer_list<VtuArray> cells, const AppendedData& data) {
  std::string xml;
  char buf[512];
  xml += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
         "byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n";
  std::snprintf(buf, sizeof(buf), "<Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">\n", num_points, num_cells);
  xml += buf;
  auto array = [&](const VtuArray& a) {
    std::snprintf(buf, sizeof(buf), "<DataArray type=\"%s\" Name=\"%s\" NumberOfComponents=\"%d\" "
                  "format=\"appended\" offset=\"%lld\"/>\n", a.type, a.name, a.components,
                  static_cast<long long>(a.offset));
    xml += buf;
  };
  xml += std::string("<PointData ") + point_attributes + ">\n";
  for (const VtuArray& a : point_data) array(a);
  xml += "</PointData>\n<Points>\n";
  array(points);
  xml += "</Points>\n<Cells>\n";
  for (const VtuArray& a : cells) array(a);
  xml += "</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_";
  xml += data.bytes();
  xml += "\n</AppendedData>\n</VTKFile>\n";
  return xml;
}

}  // namespace

namespace {
std::vector<int32_t> concatenated(const std::vector<int32_t>& a, const std::vector<int32_t>& b) {
  std::vector<int32_t> out(a);
  out.insert(out.end(), b.begin(), b.end());
  return out;
}
}  // namespace

std::string vtu_document(const Model& model, const std::vector<double>& x, const std::vector<double>& v) {
  AppendedData data;
  // The tets of tet bodies, then those of affine bodies (which carry no elastic tets).
  const size_t nv = static_cast<size_t>(model.num_vertices);
  const size_t nt = static_cast<size_t>(model.num_tets) + model.affine_tets.size() / 4;
  std::vector<int32_t> offsets(nt);
  for (size_t t = 0; t < nt; ++t) offsets[t] = static_cast<int32_t>(4 * (t + 1));
  const std::vector<uint8_t> types(nt, 10);  // VTK_TETRA
  const int64_t o_points = data.add(x.data(), 3 * nv);
  const int64_t o_conn = model.affine_tets.empty()
                             ? data.add(model.tets.data(), 4 * nt)
                             : data.add(concatenated(model.tets, model.affine_tets).data(), 4 * nt);
  const int64_t o_offsets = data.add(offsets.data(), nt);
  const int64_t o_types = data.add(types.data(), nt);
  const int64_t o_velocity = data.add(v.data(), 3 * nv);
  const int64_t o_body = data.add(model.vertex_body.data(), nv);
  return vtu_file(nv, nt, "Vectors=\"velocity\"",
                  {{"Float64", "velocity", 3, o_velocity}, {"Int32", "body", 1, o_body}},
                  {"Float64", "Points", 3, o_points},
                  {{"Int32", "connectivity", 1, o_conn}, {"Int32", "offsets", 1, o_offsets},
                   {"UInt8", "types", 1, o_types}},
                  data);
}

std::string vtu_particles_document(const Particles& particles, const std::vector<int32_t>& particle_body,
                                   const std::vector<Material>& materials) {
  const size_t n = static_cast<size_t>(particles.size());
  std::vector<int64_t> connectivity(n), offsets(n);
  std::vector<double> J(n), von_mises(n), radius(n);
  for (size_t p = 0; p < n; ++p) {
    connectivity[p] = static_cast<int64_t>(p);
    offsets[p] = static_cast<int64_t>(p + 1);
    const Eigen::Matrix3d F = particles.deformation(static_cast<int64_t>(p));
    const Material& m = materials[particles.material[p]];
    J[p] = F.determinant();
    radius[p] = 0.5 * std::cbrt(std::abs(J[p]) * particles.volume0[p]);
    const Eigen::Matrix3d sigma = pk1(m.model, F, m.lame) * F.transpose() / J[p];
    const Eigen::Matrix3d deviator = sigma - sigma.trace() / 3.0 * Eigen::Matrix3d::Identity();
    von_mises[p] = std::sqrt(1.5 * deviator.squaredNorm());
  }
  const std::vector<uint8_t> types(n, 1);  // VTK_VERTEX
  AppendedData data;
  const int64_t o_points = data.add(particles.x.data(), 3 * n);
  const int64_t o_conn = data.add(connectivity.data(), n);
  const int64_t o_offsets = data.add(offsets.data(), n);
  const int64_t o_types = data.add(types.data(), n);
  const int64_t o_velocity = data.add(particles.v.data(), 3 * n);
  const int64_t o_J = data.add(J.data(), n);
  const int64_t o_von_mises = data.add(von_mises.data(), n);
  const int64_t o_body = data.add(particle_body.data(), n);
  const int64_t o_radius = data.add(radius.data(), n);
  return vtu_file(n, n, "Vectors=\"velocity\" Scalars=\"von_mises\"",
                  {{"Float64", "velocity", 3, o_velocity}, {"Float64", "J", 1, o_J},
                   {"Float64", "von_mises", 1, o_von_mises}, {"Int32", "body", 1, o_body},
                   {"Float64", "radius", 1, o_radius}},
                  {"Float64", "Points", 3, o_points},
                  {{"Int64", "connectivity", 1, o_conn}, {"Int64", "offsets", 1, o_offsets},
                   {"UInt8", "types", 1, o_types}},
                  data);
}

std::string obj_document(const Model& model, const std::vector<double>& x) {
  std::string out;
  out.reserve(static_cast<size_t>(model.num_vertices) * 40 + model.surface_triangles.size() * 12);
  char buf[128];
  for (int32_t i = 0; i < model.num_vertices; ++i) {
    const int n = std::snprintf(buf, sizeof(buf), "v %.9g %.9g %.9g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    out.append(buf, static_cast<size_t>(n));
  }
  // Obstacle meshes are scenery, not results (DESIGN.md section 6): their triangles are left
  // out, while their vertices stay in the "v" list so that numbering remains global.
  for (size_t t = 0; t + 2 < model.surface_triangles.size(); t += 3) {
    if (model.bodies[model.vertex_body[model.surface_triangles[t]]].obstacle) continue;
    const int n = std::snprintf(buf, sizeof(buf), "f %d %d %d\n", model.surface_triangles[t] + 1,
                                model.surface_triangles[t + 1] + 1, model.surface_triangles[t + 2] + 1);
    out.append(buf, static_cast<size_t>(n));
  }
  return out;
}

std::string pvd_document(const std::vector<std::pair<double, std::string>>& frames) {
  std::string xml = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
  char buf[512];
  for (const auto& [time, file] : frames) {
    std::snprintf(buf, sizeof(buf), "<DataSet timestep=\"%.17g\" group=\"\" part=\"0\" file=\"%s\"/>\n",
                  time, file.c_str());
    xml += buf;
  }
  xml += "</Collection>\n</VTKFile>\n";
  return xml;
}

}  // namespace nexdyn
