// One MPM step under the engine's integrator family (seed 002, "MPM"; issue 23).
//
// The grid carries the step: after particle-to-grid, every node i with mass (an "active" node)
// has m_i, v_i^n, the seed's acceleration a_i^n = f_i^n / m_i (elastic force of the particles at
// the start of the step, plus gravity) and, under generalized-alpha, the auxiliary acceleration
// abar_i^n (carried by the particles). Writing the node's step displacement u_i = x_i^{n+1} - x_i^n,
// the step minimises the grid incremental potential of integrator.hpp with x_n = 0:
//
//   u_tilde = h v + alpha (1 - 2 beta) h^2 abar + 2 alpha beta h^2 (c_f a - c_m abar)
//   E(u)    = 1/2 sum_i m_i |u_i - u_tilde_i|^2 + s (E_el(u) - sum_i m_i g . u_i)
//
// with E_el of engine/mpm/grid_elasticity.hpp and s = 2 alpha beta h^2 c_a, then updates a, abar
// and v on the grid with the family's rules (update_implicit), and moves the particles with the
// grid (grid-to-particle: v, C, x += sum w u, F <- (I + sum u grad w^T) F). Explicit schemes
// (beta = 0) take u = u_tilde and a_{n+1} = f(u) / m.
//
// The solve is Newton's method with a backtracking line search on E (a neo-Hookean particle
// turned inside out makes E infinite, so the line search never accepts one), and the engine's
// stopping rule on the particles: the largest particle move sum_i w_ip d_i of an increment, divided
// by the step's dt, below solver.tolerance (nodes at the fringe of the stencils carry almost no
// mass, and their own increments say little). Its linear
// systems are solved by conjugate gradients preconditioned with the 3x3 diagonal blocks, on the
// Hessian M + s K held in factored form: per particle V_p times the PSD-projected dP/dF
// (81 numbers), and the stencil's g_ip = F_p^nT grad w_ip recomputed from the weights, so a
// product K w costs about 600 flops per particle and a 27 x 27-node block is never formed. The
// grid Hessian couples each node with the 125 nodes of a 5^3 box, so a sparse Cholesky of it
// fills in fast: one CHOLMOD factorisation of it costs about a whole PCG step already at 4,000
// particles (bench/bench_mpm_cholmod.cpp, docs/performance.md "MPM").
//
// Boundary conditions act on nodes (docs/scenes.md, "MPM: particle bodies"): a node inside a `boundary` box follows
// the box's motion; a node on or behind a plane is held (sticky), keeps its normal position
// (slip), or may not move into the plane but may leave it (separating: an inequality, kept by
// a projected Newton method with an active set; Coulomb friction then takes up to
// mu h |f_n| / m_i of the node's tangential velocity). A node under two planes' slip or
// separating conditions is held.
//
// Determinism: every particle-to-node scatter is the coloured one of engine/mpm/transfer.hpp and
// every dot product a chunked sum in node order, so a step gives the same bits on any number of
// threads.
#pragma once

#include "engine/integrator.hpp"
#include "engine/mpm/grid.hpp"
#include "engine/mpm/mpm_model.hpp"
#include "engine/mpm/particles.hpp"
#include "engine/mpm/transfer.hpp"
#include "engine/step_result.hpp"
#include "engine/step_profile.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace nexdyn {

// Compact node entries per chunk of the Newton system's sums (mpm_step_system.cpp).
inline constexpr int64_t kMpmNodeGrain = 4096;

struct MpmStepSettings {
  IntegratorParams integrator;
  double tolerance = 1e-5;   // [m/s] Newton stops when max |increment| / h is below it
  int max_iterations = 100;  // Newton iterations per step
  double pcg_tolerance = 1e-5;  // relative residual of each linear solve
};

struct MpmStepResult {
  bool ok = true;
  StepStatus status = StepStatus::ok;  // why it failed, for stats and the retry
  std::string message;          // why the step failed
  bool retry_may_help = true;   // false when a smaller step cannot help (particles left the grid)
  int newton_iterations = 0;
  int64_t pcg_iterations = 0;
  int64_t boundary_nodes = 0;   // nodes held or pushed by a plane at the end of the step
  int64_t active_nodes = 0;
};

// Particle state besides Particles that the integrator family needs: the auxiliary acceleration
// abar of generalized-alpha, carried on the particles from step to step (3 per particle; zero and
// unused by the schemes with alpha_m = alpha_f, whose abar is the grid's a).
struct MpmParticleHistory {
  std::vector<double> a_bar;
};

class MpmStepper {
 public:
  explicit MpmStepper(const MpmModel& model);

  // Advances `particles` from t to t + dt. On failure nothing is changed.
  MpmStepResult advance(Particles& particles, MpmParticleHistory& history, double t, double dt,
                        const MpmStepSettings& settings, StepProfile* profile = nullptr);

  const Grid& grid() const { return grid_; }

 private:
  enum Hold : uint8_t { kFree = 0, kNormal = 1, kFull = 2 };

  // ---- stages of advance ----
  bool transfer_to_grid(const Particles& particles, const MpmParticleHistory& history, bool with_abar);
  void start_of_step_acceleration(const Particles& particles);
  void set_boundary(double t, double dt);
  void project_start(std::vector<double>& u) const;
  bool newton(const Particles& particles, double dt, double s, const MpmStepSettings& settings,
              MpmStepResult& result, StepProfile* profile);
  void finish_velocities(double dt);
  void transfer_to_particles(Particles& particles, MpmParticleHistory& history, bool with_abar);

  // ---- pieces of the Newton solve (mpm_step_system.cpp) ----
  double energy(const Particles& particles, const std::vector<double>& u, double s);
  double gradient_and_stiffness(const Particles& particles, const std::vector<double>& u, double s,
                                std::vector<double>& g);
  void apply_hessian(const Particles& particles, double s, const std::vector<double>& w,
                     std::vector<double>& out);
  int64_t conjugate_gradients(const Particles& particles, double s, const std::vector<double>& rhs,
                              double tolerance, std::vector<double>& x);
  void project(std::vector<double>& w) const;
  void invert_projected_blocks();
  double particle_increment(const Particles& particles, const std::vector<double>& w);
  void scatter_to_dense(const std::vector<double>& compact, std::vector<double>& dense) const;

  const MpmModel& model_;
  Grid grid_;
  ParticleBins bins_;
  std::vector<int32_t> active_;        // active node ids, ascending
  std::vector<int32_t> active_index_;  // (num_nodes) position in active_, or -1
  // Per active node (compact): mass, and 3 per node for the rest.
  std::vector<double> m_, v_, a_, a_bar_, u_tilde_, u_;
  std::vector<uint8_t> hold_;          // Hold per active node
  std::vector<uint8_t> separating_;    // 1: the node's normal constraint is a separating one
  std::vector<double> normal_;         // 3 per active node (kNormal)
  std::vector<double> target_;         // 3 per active node: prescribed displacement (boxes)
  std::vector<double> box_velocity_;   // 3 per active node: the box's velocity at t + dt
  std::vector<uint8_t> in_box_;
  std::vector<double> normal_force_;   // per active node: the plane's normal force s^-1 g . n
  // Per particle: V_p times the projected dP/dF at the current iterate (81).
  std::vector<double> stiffness_;
  std::vector<double> diag_;           // 9 per active node: the diagonal blocks, then inverted
  std::vector<double> diag_raw_;       // the blocks m I + s D before projection
  std::vector<double> dense_u_, dense_v_, dense_work_;
  std::vector<double> particle_energy_;
  std::vector<double> chunk_max_;       // per chunk of particles: the largest move (particle_increment)
  // Conjugate-gradient scratch.
  std::vector<double> r_, z_, p_, q_, d_, g_, trial_;
};

}  // namespace nexdyn
