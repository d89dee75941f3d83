// IPC's lagged friction over the contact stencils (issue 4; kernels/friction/friction.hpp has
// the per-contact math and why lagging makes friction a potential).
//
// lag() freezes, at positions x^t, one friction stencil per barrier stencil of the active set
// built at x^t: its tangent basis, closest-point weights and normal force lambda (times the
// stencil's multiplicity, and the mollifier of a nearly parallel edge pair). Until the next
// lag(), the friction potential of the step is
//   D(x) = sum_k lambda_k F0_k(|T_k^T (x - x_n)|),   eps_u = epsv dt,
// F0_k the smoothed Coulomb potential of the contact's static and kinetic coefficients (mu f0
// for one coefficient; kernels/friction/friction.hpp), looked up per pair of materials,
// with x_n the positions at the start of the step. Like the barrier's, its derivatives are stored
// per stencil at the stencil's real size (3n gradient, 3n x 3n PSD slab) and gathered by the
// caller in stencil order, so results do not depend on the number of threads.
#pragma once

#include "engine/contact/barrier_potential.hpp"
#include "engine/model.hpp"
#include "kernels/friction/friction_types.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

// Coefficients of every pair of contact materials: indices of model.materials, plus one more,
// none(), for obstacles without a material. Symmetric.
class FrictionTable {
 public:
  FrictionTable(int32_t num_materials, FrictionCoefficients fallback)
      : size_(num_materials + 1), table_(size_t(size_) * size_, fallback) {}
  int32_t none() const { return size_ - 1; }
  void set(int32_t a, int32_t b, FrictionCoefficients c) { table_[a * size_ + b] = table_[b * size_ + a] = c; }
  const FrictionCoefficients& operator()(int32_t a, int32_t b) const { return table_[a * size_ + b]; }
  // Some pair holds harder than it slides (mu_s > mu_k): the step is then not convex in the slip.
  bool has_static_peak() const {
    for (const FrictionCoefficients& c : table_)
      if (c.mu_s > c.mu_k) return true;
    return false;
  }

 private:
  int32_t size_;
  std::vector<FrictionCoefficients> table_;
};

class FrictionPotential {
 public:
  // table: Coulomb coefficients per material pair; epsv: slip speed below which a contact counts
  // as sticking [m/s].
  FrictionPotential(const Model& model, FrictionTable table, double epsv);

  // Bases and normal forces at x_lag from barrier's active set, which must have been built at
  // x_lag (BarrierPotential::build_active_set) with barrier stiffness kappa; x_start: positions
  // at the start of the step, whose stencil vertices the lag copies (the slip is measured from
  // them until the next lag, whatever becomes of x_start); dt: the time step.
  void lag(const BarrierPotential& barrier, const double* x_lag, double kappa, const double* x_start,
           double dt);
  // No friction stencils (no contact at the lagged positions, or before the first lag).
  void clear();
  // Appends to `out` (4 ids per stencil, as stencils()) the contacts whose friction force the
  // last lag() changed by more than a re-solve could resolve: those where dt * |change| / m
  // exceeds velocity_tolerance [m/s], m the lightest free vertex of the stencil. The change is
  // bounded by mu (|lambda_new - lambda_old| + lambda_new max_i |w_i P P^T new - old|), a
  // contact that appears or disappears by mu lambda. Returns how many it appended.
  int64_t append_changed_stencils(double dt, double velocity_tolerance, std::vector<int32_t>& out) const;

  const FrictionTable& table() const { return table_; }
  int64_t num_stencils() const { return static_cast<int64_t>(basis_.size()); }
  // Sum of the lagged normal forces [N]: the lagging loop compares it between lags.
  double total_normal_force() const { return total_normal_force_; }

  // total[g] += the energy of the stencils whose moving vertices are in group g
  // (group_of_vertex[v], -1 = does not move).
  void group_energy(const double* x, const int32_t* group_of_vertex, double* total) const;
  double energy(const double* x) const;
  // Derivatives of weight * D at x; layout as BarrierPotential's (stencils, slab_begin), and as
  // there only the stencils with an `active` vertex when given.
  //
  // The Hessian is exact, except at contacts whose slip has reversed: while a contact slides, D
  // is linear along the slip and its Hessian zero there, so a Newton step that should bring the
  // slip to rest carries it across u = 0 and the line search halves the step of the contact's
  // whole group, iteration after iteration (docs/performance.md, "Friction that reverses"). A
  // stencil whose slip u points against the one at the iterate before (within this lag) takes
  // the majorized Hessian (friction_hessian, kernels/friction/friction.hpp), whose steps reach the
  // kink without crossing it, until its slip grows again (it slides after all). Called with
  // with_hessian once per Newton iterate: it updates that memory.
  void compute_derivatives(const double* x, double weight, bool with_hessian,
                           const uint8_t* active = nullptr);
  void add_gradient(double* grad) const;
  // The same with the held vertices' entries too (the force on a moving boundary).
  void add_gradient_with_held(double* grad) const;
  const std::vector<int32_t>& stencils() const { return stencils_; }       // (num x 4), -1 = held/absent
  const std::vector<int64_t>& slab_begin() const { return slab_begin_; }   // (num + 1)
  const std::vector<double>& local_hessians() const { return hessians_; }

 private:
  Vector12d displacement(const double* x, int64_t k) const;
  // Whether stencil k takes the majorized Hessian at slip u, which becomes its last slip.
  bool track_slip(int64_t k, const Eigen::Vector2d& u);

  // Material slot of a vertex's body, or of obstacle plane `plane`, in table_.
  int32_t vertex_material(int32_t v) const;
  int32_t plane_material(int32_t plane) const;

  const Model& model_;
  FrictionTable table_;
  double epsv_ = 0.0, eps_u_ = 0.0;
  double total_normal_force_ = 0.0;
  std::vector<FrictionBasis> basis_;     // (num)
  std::vector<FrictionCoefficients> mu_; // (num) of the two sides' materials
  std::vector<double> normal_force_;     // (num) lambda, multiplicity included [N]
  std::vector<double> start_;            // (num x 12) the stencil vertices at the step's start [m]
  std::vector<int32_t> vertices_;        // (num x 4) real vertex ids, -1 past n
  std::vector<int32_t> stencils_;        // (num x 4) as vertices_, held vertices -1
  std::vector<int32_t> keys_;            // (num x 5) kind and the barrier's stencil vertices
  // The lag before the last one (append_changed_stencils).
  struct Lag {
    std::vector<FrictionBasis> basis;
    std::vector<FrictionCoefficients> mu;
    std::vector<double> normal_force;
    std::vector<int32_t> stencils, keys;
  } previous_;
  std::vector<int64_t> slab_begin_;      // (num + 1)
  std::vector<double> gradients_;        // (num x 12)
  std::vector<double> hessians_;         // (slab_begin_.back())
  // Slip reversals (compute_derivatives): each stencil's slip at the last iterate whose Hessian
  // it took, and whether it takes the majorized Hessian. Reset by lag().
  std::vector<double> last_slip_;        // (num x 2) u at that iterate [m]
  std::vector<uint8_t> majorized_;       // (num)
};

}  // namespace nexdyn
