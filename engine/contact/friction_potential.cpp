// Lagged friction over the contact stencils (see friction_potential.hpp).
#include "engine/contact/friction_potential.hpp"

#include "engine/parallel.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/friction/friction.hpp"

namespace nexdyn {

namespace {

using StencilKind = BarrierPotential::StencilKind;

Eigen::Vector3d point(const double* x, int32_t v) { return Eigen::Vector3d::Map(x + 3 * int64_t{v}); }

// The basis of a nearly parallel edge pair from the closest features of its case (the two
// interiors only when the edges cross), with the weights placed on the pair's 4 vertices.
FrictionBasis mollified_edge_basis(const Eigen::Vector3d (&X)[4], EdgeEdgeCase c) {
  auto scattered = [](const FrictionBasis& sub, std::initializer_list<int> idx) {
    FrictionBasis full;
    full.P = sub.P;
    full.w.setZero();
    int i = 0;
    for (int k : idx) full.w(k) = sub.w(i++);
    full.num_points = 4;
    return full;
  };
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return scattered(point_point_friction_basis(X[0], X[2]), {0, 2});
    case EdgeEdgeCase::ea0_eb1: return scattered(point_point_friction_basis(X[0], X[3]), {0, 3});
    case EdgeEdgeCase::ea1_eb0: return scattered(point_point_friction_basis(X[1], X[2]), {1, 2});
    case EdgeEdgeCase::ea1_eb1: return scattered(point_point_friction_basis(X[1], X[3]), {1, 3});
    case EdgeEdgeCase::ea_eb0: return scattered(point_edge_friction_basis(X[2], X[0], X[1]), {2, 0, 1});
    case EdgeEdgeCase::ea_eb1: return scattered(point_edge_friction_basis(X[3], X[0], X[1]), {3, 0, 1});
    case EdgeEdgeCase::ea0_eb: return scattered(point_edge_friction_basis(X[0], X[2], X[3]), {0, 2, 3});
    case EdgeEdgeCase::ea1_eb: return scattered(point_edge_friction_basis(X[1], X[2], X[3]), {1, 2, 3});
    case EdgeEdgeCase::ea_eb: break;
  }
  return edge_edge_friction_basis(X[0], X[1], X[2], X[3]);
}

}  // namespace

FrictionPotential::FrictionPotential(const Model& model, FrictionTable table, double epsv)
    : model_(model), table_(std::move(table)), epsv_(epsv) {}

int32_t FrictionPotential::vertex_material(int32_t v) const {
  const int32_t m = model_.bodies[model_.vertex_body[v]].material;
  return m >= 0 ? m : table_.none();
}

int32_t FrictionPotential::plane_material(int32_t plane) const {
  const int32_t m = model_.obstacle_planes[plane].material;
  return m >= 0 ? m : table_.none();
}

void FrictionPotential::clear() {
  basis_.clear();
  mu_.clear();
  normal_force_.clear();
  vertices_.clear();
  stencils_.clear();
  start_.clear();
  slab_begin_.assign(1, 0);
  last_slip_.clear();
  majorized_.clear();
  total_normal_force_ = 0.0;
}

bool FrictionPotential::track_slip(int64_t k, const Eigen::Vector2d& u) {
  double* last = &last_slip_[2 * k];
  const double last_squared = last[0] * last[0] + last[1] * last[1];
  if (u.x() * last[0] + u.y() * last[1] < 0.0) majorized_[k] = 1;    // reversed: it may stick
  else if (u.squaredNorm() > last_squared) majorized_[k] = 0;         // growing: it slides
  last[0] = u.x();
  last[1] = u.y();
  return majorized_[k];
}

void FrictionPotential::lag(const BarrierPotential& barrier, const double* x, double kappa,
                            const double* x_start, double dt) {
  eps_u_ = epsv_ * dt;
  previous_.basis.swap(basis_);
  previous_.mu.swap(mu_);
  previous_.normal_force.swap(normal_force_);
  previous_.stencils.swap(stencils_);
  previous_.keys.swap(keys_);
  const int64_t num = barrier.num_stencils();
  const double dhat2 = barrier.dhat() * barrier.dhat();
  const std::vector<StencilKind>& kinds = barrier.kinds();
  const std::vector<int32_t>& real = barrier.stencil_vertices();
  const std::vector<int32_t>& multiplicity = barrier.multiplicities();
  basis_.resize(num);
  last_slip_.assign(2 * num, 0.0);
  majorized_.assign(num, 0);
  mu_.resize(num);
  normal_force_.resize(num);
  vertices_.assign(4 * num, -1);
  stencils_.assign(4 * num, -1);
  start_.assign(12 * num, 0.0);
  keys_.resize(5 * num);
  slab_begin_.resize(num + 1);
  slab_begin_[0] = 0;
  parallel_for(num, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const int32_t* v = &real[4 * k];
      const int n = BarrierPotential::stencil_size(kinds[k]);
      keys_[5 * k] = static_cast<int32_t>(kinds[k]);
      std::copy_n(v, 4, &keys_[5 * k + 1]);
      Eigen::Vector3d X[4];
      for (int i = 0; i < n && kinds[k] != StencilKind::vertex_plane; ++i) X[i] = point(x, v[i]);
      double d = 0.0, scale = multiplicity[k];
      FrictionBasis& basis = basis_[k];
      switch (kinds[k]) {
        case StencilKind::vertex_plane: {
          const ObstaclePlane& plane = model_.obstacle_planes[v[1]];
          const double h = (point(x, v[0]) - plane.point).dot(plane.normal);
          d = h * h;
          basis = vertex_plane_friction_basis(plane.normal);
          break;
        }
        case StencilKind::point_point:
          d = point_point_distance(X[0], X[1]);
          basis = point_point_friction_basis(X[0], X[1]);
          break;
        case StencilKind::point_edge:
          d = point_line_distance(X[0], X[1], X[2]);
          basis = point_edge_friction_basis(X[0], X[1], X[2]);
          break;
        case StencilKind::point_triangle:
          d = point_plane_distance(X[0], X[1], X[2], X[3]);
          basis = point_triangle_friction_basis(X[0], X[1], X[2], X[3]);
          break;
        case StencilKind::edge_edge:
          d = line_line_distance(X[0], X[1], X[2], X[3]);
          basis = edge_edge_friction_basis(X[0], X[1], X[2], X[3]);
          break;
        case StencilKind::edge_edge_mollified: {
          const EdgeEdgeCase c = edge_edge_case(X[0], X[1], X[2], X[3]);
          d = edge_edge_distance(X[0], X[1], X[2], X[3], c);
          const double* r = model_.rest_positions.data();
          const double eps_x = edge_edge_mollifier_threshold(point(r, v[0]), point(r, v[1]), point(r, v[2]), point(r, v[3]));
          scale *= edge_edge_mollifier(X[0], X[1], X[2], X[3], eps_x);
          basis = mollified_edge_basis(X, c);
          break;
        }
      }
      normal_force_[k] = scale * friction_normal_force(d, dhat2, kappa);
      // Side A is the stencil's first vertex; side B its last (a plane, a triangle or edge b).
      const int32_t side_b = kinds[k] == StencilKind::vertex_plane ? plane_material(v[1]) : vertex_material(v[n - 1]);
      mu_[k] = table_(vertex_material(v[0]), side_b);
      const int points = kinds[k] == StencilKind::vertex_plane ? 1 : n;
      for (int i = 0; i < points; ++i) {
        vertices_[4 * k + i] = v[i];
        Eigen::Vector3d::Map(&start_[12 * k + 3 * i]) = point(x_start, v[i]);
        stencils_[4 * k + i] = model_.eliminated(v[i]) ? -1 : v[i];
      }
      slab_begin_[k + 1] = 9 * points * points;
    }
  }, 1024);
  total_normal_force_ = 0.0;
  for (int64_t k = 0; k < num; ++k) {
    slab_begin_[k + 1] += slab_begin_[k];
    total_normal_force_ += normal_force_[k];
  }
}

int64_t FrictionPotential::append_changed_stencils(double dt, double velocity_tolerance,
                                                   std::vector<int32_t>& out) const {
  // The previous lag's contacts by key, to find each new contact's old self.
  const int64_t num = num_stencils(), num_old = static_cast<int64_t>(previous_.basis.size());
  auto key = [](const std::vector<int32_t>& keys, int64_t k) { return &keys[5 * k]; };
  auto less = [](const int32_t* a, const int32_t* b) { return std::lexicographical_compare(a, a + 5, b, b + 5); };
  std::vector<int64_t> old_order(num_old);
  for (int64_t k = 0; k < num_old; ++k) old_order[k] = k;
  std::sort(old_order.begin(), old_order.end(), [&](int64_t a, int64_t b) {
    return less(key(previous_.keys, a), key(previous_.keys, b));
  });
  std::vector<uint8_t> old_matched(num_old, 0);
  // The smallest velocity change the contact's force change can make on its lightest vertex.
  auto exceeds = [&](const int32_t* stencil, double force_change) {
    double m = INFINITY;
    for (int i = 0; i < 4; ++i) {
      if (stencil[i] < 0) continue;
      // A follower of an affine body moves with the body's mass (its own is 0).
      const int32_t v = model_.follows_body(stencil[i]) ? model_.affine_bodies[model_.follows[stencil[i]]].node
                                                        : stencil[i];
      const double mi = model_.mass[v];
      if (mi > 0.0) m = std::min(m, mi);
    }
    return std::isfinite(m) && dt * force_change > velocity_tolerance * m;
  };
  auto projector = [](const FrictionBasis& b, int i) -> Eigen::Matrix3d { return b.w[i] * b.P * b.P.transpose(); };
  const int64_t before = static_cast<int64_t>(out.size());
  for (int64_t k = 0; k < num; ++k) {
    const int32_t* stencil = &stencils_[4 * k];
    const double mu = std::max(mu_[k].mu_s, mu_[k].mu_k);
    auto it = std::lower_bound(old_order.begin(), old_order.end(), key(keys_, k), [&](int64_t o, const int32_t* kk) {
      return less(key(previous_.keys, o), kk);
    });
    double change = mu * normal_force_[k];  // a new contact
    if (it != old_order.end() && std::equal(key(keys_, k), key(keys_, k) + 5, key(previous_.keys, *it))) {
      const int64_t o = *it;
      old_matched[o] = 1;
      double turn = 0.0;
      for (int i = 0; i < basis_[k].num_points; ++i)
        turn = std::max(turn, (projector(basis_[k], i) - projector(previous_.basis[o], i)).cwiseAbs().maxCoeff());
      change = mu * (std::abs(normal_force_[k] - previous_.normal_force[o]) + normal_force_[k] * turn);
    }
    if (exceeds(stencil, change)) out.insert(out.end(), stencil, stencil + 4);
  }
  for (int64_t o = 0; o < num_old; ++o) {  // contacts that are gone
    const int32_t* stencil = &previous_.stencils[4 * o];
    const double mu = std::max(previous_.mu[o].mu_s, previous_.mu[o].mu_k);
    if (!old_matched[o] && exceeds(stencil, mu * previous_.normal_force[o])) out.insert(out.end(), stencil, stencil + 4);
  }
  return (static_cast<int64_t>(out.size()) - before) / 4;
}

Vector12d FrictionPotential::displacement(const double* x, int64_t k) const {
  Vector12d dx = Vector12d::Zero();
  for (int i = 0; i < 4; ++i) {
    const int32_t v = vertices_[4 * k + i];
    if (v >= 0) dx.segment<3>(3 * i) = point(x, v) - Eigen::Vector3d::Map(&start_[12 * k + 3 * i]);
  }
  return dx;
}

double FrictionPotential::energy(const double* x) const {
  return deterministic_sum(num_stencils(), [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t k = begin; k < end; ++k)
      sum += friction_energy(basis_[k], displacement(x, k), mu_[k], normal_force_[k], eps_u_);
    return sum;
  }, 1024);
}

void FrictionPotential::group_energy(const double* x, const int32_t* group_of_vertex, double* total) const {
  grouped_sum(num_stencils(), 1024, [&](int64_t k) {
    for (int a = 0; a < 4; ++a) {
      const int32_t v = stencils_[4 * k + a];
      if (v >= 0 && group_of_vertex[v] >= 0) return group_of_vertex[v];
    }
    return -1;
  }, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t k = begin; k < end; ++k)
      sum += friction_energy(basis_[k], displacement(x, k), mu_[k], normal_force_[k], eps_u_);
    return sum;
  }, total);
}

void FrictionPotential::compute_derivatives(const double* x, double weight, bool with_hessian,
                                            const uint8_t* active) {
  const int64_t num = num_stencils();
  gradients_.resize(12 * num);
  if (with_hessian) hessians_.resize(slab_begin_[num]);
  parallel_for(num, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      if (!touches(&stencils_[4 * k], active)) {
        std::fill(&gradients_[12 * k], &gradients_[12 * k] + 12, 0.0);
        continue;
      }
      const Vector12d dx = displacement(x, k);
      Eigen::Map<Vector12d>{&gradients_[12 * k]} =
          weight * friction_gradient(basis_[k], dx, mu_[k], normal_force_[k], eps_u_);
      if (!with_hessian) continue;
      const bool majorize = track_slip(k, tangential_displacement(basis_[k], dx));
      const Matrix12d H = weight * friction_hessian(basis_[k], dx, mu_[k], normal_force_[k], eps_u_, majorize);
      const int size = 3 * basis_[k].num_points;
      double* slab = &hessians_[slab_begin_[k]];
      for (int c = 0; c < size; ++c)
        for (int r = 0; r < size; ++r) slab[c * size + r] = H(r, c);
    }
  }, 256);
}

void FrictionPotential::add_gradient(double* grad) const {
  add_stencil_gradients(stencils_, gradients_, model_.num_vertices, grad);
}

void FrictionPotential::add_gradient_with_held(double* grad) const {
  add_stencil_gradients(vertices_, gradients_, model_.num_vertices, grad);
}

}  // namespace nexdyn
