// Rayleigh damping (seed 004): the force f_d = -D v_{n+1} with D = a1 K(x_n) + a2 M, per
// material ("damping": {"stiffness": a1, "mass": a2}). K is the PSD-projected elastic stiffness
// at the start of the step, so D is positive semi-definite and the force only ever takes energy out.
//
// Every scheme of the family writes the end-of-step velocity as an affine function of the unknown
// positions (engine/integrator.hpp):
//   v(x) = v_pred + k (x - x_tilde),   k = h gamma c_a / s,
//   v_pred = v_n + h ((1 - gamma) abar_n + gamma (c_f a_n - c_m abar_n)),
// so the dissipation potential
//   e(x) = 1/(2k) v(x)^T D v(x),   grad e = D v(x),   Hessian k D,
// weighted by s like every force, adds exactly s D v_{n+1} to the gradient of E: the minimiser is
// the step of M a_{n+1} = f(x_{n+1}) - D v_{n+1}. Under implicit Euler s k = h, which gives seed
// 004's [M + h D + h^2 K] system after linearisation. Explicit schemes use D at the predicted
// velocity instead (add_explicit_acceleration).
//
// Storage: the stiffness part keeps a1 K_t(x_n) per tet (engine/sparse/tet_slab_operator.hpp)
// and the same matrix in the elastic pattern's order; results do not depend on the thread
// count. Its Hessian adds to the elastic pattern's values (the term is listed after the elastic
// term).
#pragma once

#include "engine/model.hpp"
#include "engine/potential/potential_term.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "engine/sparse/tet_slab_operator.hpp"
#include "engine/state.hpp"

#include <memory>
#include <vector>

namespace nexdyn {

// Vertices per chunk of the term's per-vertex loops (its per-tet loops take 64 tets a chunk).
inline constexpr int64_t kDampingVertexGrain = 1024;

class DampingTerm final : public PotentialTerm {
 public:
  // state: the State the simulation advances; read at begin_step for x_n, v_n, a_n, abar_n.
  DampingTerm(const Model& model, const HessianPattern& pattern, const State& state);
  // Whether any material of the model damps.
  static bool wanted(const Model& model);

  const char* name() const override { return "Rayleigh damping"; }
  TermScale scale() const override { return TermScale::potential; }
  TermHessian hessian() const override { return TermHessian::pattern_values; }

  void begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) override;
  double energy(const double* x) const override;
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* out) override;
  void add_gradient(const double* x, double weight, double* grad) override;
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override;

  // D at the state's positions (x_n), for an explicit step or the start of a run.
  void prepare_at_state();
  // force = -D v (3n), with the D of the current step.
  void force(const double* v, double* force) const;
  // a -= M^-1 D v for the free vertices with mass (explicit schemes and the initial acceleration).
  void add_explicit_acceleration(const double* v, double* a) const;
  // a -= M^-1 D v(x), v(x) the step's end velocity at positions x (after begin_step).
  void add_step_acceleration(const double* x, double* a) const;

  // dv/dx of this step (0: no damping, "static"), and the parts of D: per tet a1 (of its
  // material), per vertex a2 m.
  double velocity_slope() const { return k_; }
  const std::vector<double>& tet_stiffness() const { return tet_a1_; }
  const std::vector<double>& vertex_mass_damping() const { return vertex_a2m_; }

 private:
  void compute_stiffness(const double* x);            // slabs_ and values_ at x
  void velocity(const double* x, double* v) const;    // v(x) into v (3n)
  void damped(const double* v, double* out) const;     // out = D v (3n), written
  double quadratic(const double* v) const;            // v^T D v
  double mass_quadratic(const double* v, int64_t begin, int64_t end) const;  // a2 m |v|^2, vertices [begin, end)

  const Model& model_;
  const HessianPattern& pattern_;
  const State& state_;
  bool stiffness_ = false;              // some material has a1 > 0
  std::vector<double> tet_a1_;          // (num_tets) a1 of the tet's material
  std::vector<double> vertex_a2m_;      // (num_vertices) a2 m of the vertex's body material
  std::unique_ptr<TetSlabOperator> stiffness_slabs_;  // a1 K_t(x_n); null without stiffness
  std::vector<double> values_;          // (pattern nnz) the same, in the elastic pattern
  std::vector<double> x_tilde_;         // (3n) the predictor of the step
  std::vector<double> v_pred_;          // (3n) v(x_tilde)
  double k_ = 0.0;                      // dv/dx; 0: no damping this step ("static")
  mutable std::vector<double> v_;       // (3n) scratch: v(x)
  mutable std::vector<double> dv_;      // (3n) scratch: D v
};

}  // namespace nexdyn
