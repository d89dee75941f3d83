// Projective Dynamics (Bouaziz et al. 2014) with Chebyshev semi-iterative acceleration (Wang 2015)
// for one implicit time step of tet bodies; seed 004, "Projective Dynamics".
//
// It minimises the engine's incremental potential (integrator.hpp, terms/inertia_term.hpp) for a
// corotated material with lambda = 0 (Poisson 0), where corotated is exactly the ARAP energy:
//   E(x) = sum_v m_v (1/2 |x_v - x~_v|^2 - s g . (x_v - x~_v)) + s sum_t mu_t V_t ||F_t - R_t||^2
// (gravity measured from x~ as the engine's inertia term does: the same E to the last constant).
// Whatever the materials' lambda, only the mu ||F - R||^2 part is simulated: PD's matrix has no
// room for a volume term that is not a projection.
//
// Local step: R_t = U V^T of the signed SVD of F_t(x^k) (kernels/elasticity/svd3.hpp), a proper
// rotation for inverted tets too. Global step: minimise E with the R_t fixed, a linear system
//   A x = M x~ + s M g + s sum_t 2 mu_t V_t (R_t D_t^T),   A = M + s sum_t 2 mu_t V_t D_t D_t^T,
// where F_t = X_t D_t (X_t the 3x4 corner positions, D_t the 4x3 [-1^T Dm_inv; Dm_inv]). A is the
// same matrix for x, y and z (the 12x12 G^T G of a tet is (D D^T) (x) I_3), so the solver keeps
// one scalar matrix over the free vertices and solves it for three right-hand sides: a third of
// the unknowns, a ninth of the factor, the same solution as the 3n x 3n system. A depends on
// (model, s) only: one CHOLMOD symbolic analysis per model, one numeric factorisation per s
// (a retried half step refactorises, the next full step again). Held vertices (Model::dirichlet
// >= 0, kinematic or not) stay where the caller put them: their columns move to the right-hand
// side. Local-global never increases E (each half minimises the same surrogate), so plain PD is
// a descent method; its step p = xhat - x^k equals -A^-1 grad E(x^k).
//
// Obstacle planes (Model::obstacle_planes): a vertex on the wrong side of a plane, or within
// plane_margin in front of it, at the current iterate gets the PD constraint
// w_v ||x_v - P(x_v)||^2, P the projection onto the allowed half-space. The weight is isotropic,
// so it adds w_v to the vertex's diagonal of the scalar A and nothing else: the pattern and the
// symbolic analysis stay, and only a numeric refactorisation follows a change of the active set.
// w_v = kPlaneWeight (100) times the vertex's own diagonal of A: stiff enough that a supported
// vertex sinks in by about 1% of what the same force would move it through the mesh, soft
// enough that the other 99% of a PD step still reaches it tangentially (an isotropic spring
// also drags the vertex along the plane while the iterates converge; the fixed point has no
// tangential force, since P keeps the tangential position). After the iterations every vertex
// still behind a plane is projected onto it exactly, so the result never penetrates. A vertex in
// the margin band (P(x) = x) is held in place for one global step, which keeps a resting contact
// (projected onto the plane at the end of the last step, distance 0) in the active set instead
// of letting it fall through first; the default margin is tiny for that reason.
// Joints are not supported: this class ignores Model::joints, so a caller must refuse scenes
// with joints; contact between meshes (IPC barrier, friction) is not handled either.
//
// Chebyshev (Wang 2015): after kPlainIterations plain iterations,
//   x^{k+1} = omega_{k+1} (gamma (xhat^{k+1} - x^k) + x^k - x^{k-1}) + x^{k-1},
// omega from omega = 1, 2 / (2 - rho^2), 4 / (4 - rho^2 omega), ..., gamma the under-relaxation.
// rho, the spectral radius of PD's iteration matrix I - A^-1 H, is given, or estimated from
// (model, s) alone (never from earlier steps: a run resumed from a checkpoint takes the same
// steps): the largest eigenvalue of A^-1 (A - H_rest), H_rest = the true Hessian at the rest
// shape (2 mu times the projector onto symmetric F, so A - H_rest = s sum 2 mu V G^T P_skew G),
// found by Lanczos in the A inner product (the operator is self-adjoint there) from a fixed
// start vector. It is cached per s. Or (rho_from_iterations) from the current step alone: the
// decay rate of the residual over the last kRateIterations plain iterations before Chebyshev
// starts, undone for the under-relaxation (rate = 1 - gamma (1 - rho)); a function of the step's
// own inputs, so it is checkpoint-safe too. A change of the plane active set changes A, so the
// recurrence restarts (omega = 1) there.
//
// Stopping rule, the engine's (solver/newton.hpp): converged when max|xhat^{k+1} - x^k| / dt <
// tolerance; the solution returned is xhat^{k+1}. Nothing on the step path throws: failures come
// back in PdResult with a StepStatus and a sentence. Every result is bitwise the same on any
// number of threads: per-tet work writes its own slab, per-vertex gathers read the slabs in a
// fixed order, sums are deterministic_sum, and CHOLMOD's kernels are the engine's own.
#pragma once

#include "engine/model.hpp"
#include "engine/sparse/cholmod_solver.hpp"
#include "engine/step_result.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace nexdyn {

// Tets per chunk of the per-tet passes, vertices per chunk of the gathers.
inline constexpr int64_t kPdTetGrain = 512;
inline constexpr int64_t kPdVertexGrain = 1024;

struct PdSettings {
  double tolerance = 1e-5;        // [m/s] on max|xhat - x| / dt, as Newton's increment
  int max_iterations = 2000;
  bool chebyshev = true;
  double rho = 0.0;               // spectral radius for Chebyshev, in (0, 1); 0: estimated
  bool rho_from_iterations = false;  // estimate rho from this step's plain iterations instead of
                                     // the rest shape (see the top of the file)
  double under_relaxation = 0.9;  // gamma of Wang 2015 (used with Chebyshev only)
  double plane_margin = -1.0;     // [m] band in front of a plane that activates its constraint;
                                  // < 0: 1e-6 of the model's bounding-box diagonal
};

struct PdResult {
  StepStatus status = StepStatus::ok;  // ok, max_iterations, non_finite, or a CHOLMOD failure
  int iterations = 0;                  // local-global iterations (one linear solve each)
  double residual = 0.0;               // max|xhat - x| / dt of the last iteration [m/s]
  int factorizations = 0;              // numeric factorisations during this solve
  int32_t plane_vertices = 0;          // vertices in the plane active set at the end
  std::string message;                 // why it failed; empty when ok
  bool converged() const { return status == StepStatus::ok; }
};

// Accumulated over the solver's lifetime (reset_stats() clears them).
struct PdStats {
  double local_seconds = 0.0;   // SVDs and right-hand-side slabs
  double global_seconds = 0.0;  // right-hand-side gather, three solves, scatter
  double factor_seconds = 0.0;  // numeric factorisations (and the symbolic analysis)
  double rho_seconds = 0.0;     // spectral-radius estimates
  int64_t iterations = 0;
  int64_t local_tets = 0;       // tets projected by local steps
  int64_t factorizations = 0;
};

class ProjectiveDynamics {
 public:
  // Plain iterations before Chebyshev starts: Wang 2015 waits until the iterates behave like a
  // linear iteration (its S, about 10); measured on the cantilever only.
  static constexpr int kPlainIterations = 10;
  // Plane constraint weight relative to the vertex's diagonal of A (see the top of the file).
  static constexpr double kPlaneWeight = 100.0;
  // Lanczos steps of the spectral-radius estimate at most; it stops earlier once 1 - rho moves
  // by less than kRhoTolerance relative.
  static constexpr int kMaxLanczosSteps = 120;
  static constexpr double kRhoTolerance = 1e-4;
  // Plain iterations whose residuals give the rate of rho_from_iterations.
  static constexpr int kRateIterations = 4;

  // Keeps a reference to the model. Builds the pattern and the symbolic analysis (throws
  // std::length_error beyond HessianPattern's size, like the engine's assembly: set-up, not step).
  ProjectiveDynamics(const Model& model, PdSettings settings = {});

  // One step: minimises E for the weight s (IntegratorParams::potential_scale(dt)) and predictor
  // x_tilde (3n). x (3n) holds the start on entry, held vertices at their targets, and the
  // solution on return (the last iterate when not converged).
  PdResult solve(double s, double dt, const std::vector<double>& x_tilde, std::vector<double>& x);

  // rho for s: settings.rho if given, else the estimate (cached per s).
  double spectral_radius(double s);
  // The estimate itself, whatever settings.rho says (cached per s).
  double estimated_spectral_radius(double s);

  // E(x) (the top of this file), for tests and diagnostics; held vertices count too.
  double energy(double s, const std::vector<double>& x_tilde, const std::vector<double>& x);
  // grad E(x) (3n), zero on held vertices.
  void gradient(double s, const std::vector<double>& x_tilde, const std::vector<double>& x,
                std::vector<double>& grad);

  // Appends every plain PD result xhat^{k+1} of the coming solves to `iterates` (null: stop).
  void set_history(std::vector<std::vector<double>>* iterates) { history_ = iterates; }

  const PdSettings& settings() const { return settings_; }
  void set_settings(const PdSettings& settings) { settings_ = settings; }
  const PdStats& stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }
  int32_t num_free_vertices() const { return num_free_; }

 private:
  // Matrix values for s without planes into base_values_ (deterministic: tets in order).
  void assemble_base(double s);
  // Makes the factor that of base + plane weights `plane_count_` for s; false on failure.
  bool factorize(double s, PdResult* result);
  // Local step at x: per tet 12 right-hand-side entries s (2 mu V R D^T - X_held K) into slab_.
  void local_step(double s, const double* x);
  // Per-tet values of fn(t, F, out12) gathered per free vertex into out (3 columns of num_free_).
  template <typename TetFn>
  void tet_to_vertices(TetFn&& fn, std::vector<double>& out);
  // Global step: xhat (3n) from x_tilde and the slabs; plane targets from plane_target_.
  bool global_step(double s, const double* x_tilde, double* xhat, PdResult& result);
  // Plane active set at x into plane_count_ / plane_target_.
  void update_planes(const double* x);
  void project_onto_planes(double* x) const;
  // y = A v on the three columns (num_free_ each) with the current values_.
  void multiply(const std::vector<double>& values, const std::vector<double>& v, std::vector<double>& y) const;

  const Model& model_;
  PdSettings settings_;

  // ---- free vertices and the scalar pattern (constructor) -----------------------------------
  int32_t num_free_ = 0;
  std::vector<int32_t> free_index_;   // (num_vertices) index among free vertices, -1 = held
  std::vector<int32_t> free_vertex_;  // (num_free) vertex id
  std::vector<double> weight_;        // (num_tets) 2 mu V [N m]
  std::vector<uint8_t> held_corners_; // (num_tets) bit a set: corner a is held
  std::vector<int64_t> col_ptr_, row_idx_;  // scalar upper CSC over free vertices
  std::vector<int64_t> diagonal_;     // (num_free) value index of the diagonal
  std::vector<int64_t> tet_slot_;     // (num_tets x 16) value index of K(a, b) (a, b corners,
                                      // upper entries only), -1 = held corner or lower triangle
  std::vector<int64_t> corner_ptr_;   // (num_free + 1) CSR: free vertex -> its tet corners
  std::vector<int64_t> corners_;      // tet * 4 + corner, increasing per vertex
  double bbox_diagonal_ = 0.0;        // [m]

  // ---- per s ---------------------------------------------------------------------------------
  CholmodSolver cholmod_{true};
  double base_s_ = -1.0;              // s of base_values_
  std::vector<double> base_values_;   // A without planes for base_s_
  std::vector<double> values_;        // the factorised values
  double factor_s_ = -1.0;            // s of the factor; -1: none
  std::vector<uint8_t> factor_planes_;// plane_count_ of the factor
  std::map<double, double> rho_cache_;

  // ---- per iteration -------------------------------------------------------------------------
  std::vector<double> slab_;          // (num_tets x 12) tet right-hand sides, corner-major xyz
  std::vector<double> rhs_, sol_;     // (3 x num_free) column-major x, y, z
  std::vector<uint8_t> plane_count_;  // (num_free) active plane constraints of the vertex
  std::vector<double> plane_target_;  // (num_free x 3) sum of the active projections P(x_v)

  std::vector<std::vector<double>>* history_ = nullptr;
  PdStats stats_;
};

}  // namespace nexdyn
