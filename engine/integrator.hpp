// The (alpha, beta, gamma) family of time integrators (seeds 000 and 002, DESIGN.md section 4).
//
// Every scheme is one incremental potential
//   x_tilde = x_n + h v_n + alpha (1 - 2 beta) h^2 a_n
//   E(x)    = 1/2 (x - x_tilde)^T M (x - x_tilde) + s P(x),        s = 2 alpha beta h^2
// minimised for x_{n+1}; then
//   a_{n+1} = (x_{n+1} - x_tilde) / s          (implicit, beta > 0)
//   a_{n+1} = M^-1 f(x_{n+1}), x_{n+1} = x_tilde (explicit, beta = 0: no solve)
//   v_{n+1} = v_n + h ((1 - gamma) a_n + gamma a_{n+1}).
// beta is the displacement parameter and gamma the velocity parameter (PolyFEM's JSON reader
// swaps them; seed 000, risk 3). "static" drops inertia and minimises P alone.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace nexdyn {

struct IntegratorParams {
  std::string name = "newmark";
  double alpha = 0.5;
  double beta = 0.25;
  double gamma = 0.5;
  bool is_static = false;

  bool is_explicit() const { return !is_static && beta == 0.0; }
  // The factor s in front of the potential energy in E(x).
  double potential_scale(double dt) const { return is_static ? 1.0 : 2.0 * alpha * beta * dt * dt; }
};

// The named presets of DESIGN.md; nullopt for an unknown name.
std::optional<IntegratorParams> integrator_preset(std::string_view name);
// All preset names, for error messages and documentation.
const std::vector<std::string>& integrator_preset_names();

// x_tilde = x + h v + alpha (1 - 2 beta) h^2 a over flat (3n) buffers.
void predict_x_tilde(const IntegratorParams& p, double dt, const std::vector<double>& x,
                     const std::vector<double>& v, const std::vector<double>& a,
                     std::vector<double>& x_tilde);

// After an implicit solve: a <- (x_new - x_tilde) / s, v <- v + h((1-gamma) a_old + gamma a_new).
void update_implicit(const IntegratorParams& p, double dt, const std::vector<double>& x_new,
                     const std::vector<double>& x_tilde, std::vector<double>& v,
                     std::vector<double>& a);

// After an explicit step, given a_new = M^-1 f(x_new): v <- v + h((1-gamma) a + gamma a_new), a <- a_new.
void update_explicit(const IntegratorParams& p, double dt, const std::vector<double>& a_new,
                     std::vector<double>& v, std::vector<double>& a);

}  // namespace nexdyn
