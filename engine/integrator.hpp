// The (alpha, beta, gamma) family of time integrators (seeds 000 and 002, DESIGN.md section 4),
// extended by the generalized-alpha weights (alpha_m, alpha_f) of Chung and Hulbert (1993).
//
// Every scheme is one incremental potential
//   x_tilde = x_n + h v_n + alpha (1 - 2 beta) h^2 abar_n + 2 alpha beta h^2 (c_f a_n - c_m abar_n)
//   E(x)    = 1/2 (x - x_tilde)^T M (x - x_tilde) + s P(x),   s = 2 alpha beta h^2 c_a
// minimised for x_{n+1}; then
//   a_{n+1}    = (x_{n+1} - x_tilde) / s                       the acceleration M^-1 f(x_{n+1})
//   abar_{n+1} = c_a a_{n+1} + c_f a_n - c_m abar_n            the Newmark update's acceleration
//   v_{n+1}    = v_n + h ((1 - gamma) abar_n + gamma abar_{n+1})
// with c_a = (1 - alpha_f) / (1 - alpha_m), c_f = alpha_f / (1 - alpha_m), c_m = alpha_m / (1 - alpha_m).
//
// Generalized-alpha in the form of Arnold and Bruls (2007, "Convergence of the generalized-alpha
// scheme for constrained mechanical systems"): equilibrium M a_{n+1} = f(x_{n+1}) holds at the end
// of the step, and the numerical damping lives in the auxiliary acceleration abar, defined by
//   (1 - alpha_m) abar_{n+1} + alpha_m abar_n = (1 - alpha_f) a_{n+1} + alpha_f a_n.
// For linear problems it has Chung and Hulbert's spectrum; it is second order when
// gamma = 1/2 - alpha_m + alpha_f. Because every force is evaluated at x_{n+1}, the step stays a
// minimisation of E(x) above, with the barrier and CCD where the intersection-free guarantee
// lives, and nothing is ever evaluated at an intermediate configuration that could be inverted.
// With alpha_m = alpha_f (Newmark: both 0) abar = a, and every extra term is an exact zero, so
// those schemes take the same steps bit for bit as without the extension.
//
// beta is the displacement parameter and gamma the velocity parameter (PolyFEM's JSON reader
// swaps them; seed 000, risk 3). "static" drops inertia and minimises P alone.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
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
  // Generalized-alpha weights of the old step in the inertia (alpha_m) and in the forces
  // (alpha_f); 0 and 0 for the plain (alpha, beta, gamma) schemes.
  double alpha_m = 0.0;
  double alpha_f = 0.0;
  // The spectral radius at infinite frequency the weights came from (NaN: not given).
  double rho_inf = std::numeric_limits<double>::quiet_NaN();

  bool is_explicit() const { return !is_static && beta == 0.0; }
  bool is_implicit_euler() const {
    return !is_static && alpha == 1.0 && beta == 0.5 && gamma == 1.0 && alpha_m == alpha_f;
  }
  // The weights c_a, c_f, c_m of the auxiliary acceleration (see the top of this file).
  double c_a() const { return (1.0 - alpha_f) / (1.0 - alpha_m); }
  double c_f() const { return alpha_f / (1.0 - alpha_m); }
  double c_m() const { return alpha_m / (1.0 - alpha_m); }
  // The factor s in front of the potential energy in E(x).
  double potential_scale(double dt) const {
    return is_static ? 1.0 : 2.0 * alpha * beta * dt * dt * c_a();
  }
  // The weight of joint forces in E(x): the one that makes the velocity update add exactly
  // h M^-1 f for such a force f (engine/potential/incremental_potential.hpp), relative to s.
  double joint_weight() const { return is_static ? 1.0 : 1.0 / (gamma * c_a()); }

  // Contact and friction forces act as one impulse at the end of the step: the velocity gains
  // h M^-1 f_{n+1}, the position r h^2 M^-1 f_{n+1} + (alpha - r) h^2 M^-1 f_n, where f_n is the
  // contact force at the start of the step (engine/simulation.cpp, "contact memory"). The
  // second term makes a resting contact, f_n = f_{n+1}, move the position by alpha h^2 M^-1 f
  // exactly as any steady force does, so a body at rest stays at rest with zero velocity; the
  // weight r sets how fast the chatter of a contact too stiff for the step dies out: per step by
  // the factor rho_inf under generalized-alpha (down to 1/3, the fastest this form reaches), not
  // at all at r = 1/2 (Newmark), at once at r = alpha = 1 (implicit Euler). The plain schemes
  // keep r = 2 alpha beta / gamma: Newmark's 1/2, implicit Euler's 1.
  double contact_weight() const {
    if (alpha_m == alpha_f || std::isnan(rho_inf)) return 2.0 * alpha * beta / gamma;
    const double rho = std::max(rho_inf, 1.0 / 3.0);  // roots -rho and -(r - 1/2) / (r rho)
    return (3.0 * rho + 1.0) / (2.0 * (1.0 + rho) * (1.0 + rho));
  }
  // The contact weight in E(x), r h^2 (the plain schemes: 2 alpha beta h^2 / gamma, as s / gamma).
  double contact_scale(double dt) const {
    if (is_static) return 1.0;
    if (alpha_m == alpha_f || std::isnan(rho_inf)) return 2.0 * alpha * beta * dt * dt / gamma;
    return contact_weight() * dt * dt;
  }
  // The weight of the start-of-step contact force in x_tilde, (alpha - r) h^2: exactly 0 under
  // Newmark and implicit Euler, whose r is alpha.
  double contact_memory_scale(double dt) const {
    return is_static ? 0.0 : (alpha - contact_weight()) * dt * dt;
  }
};

// The scheme of a scene that names none: generalized-alpha with rho_inf = 0.5, chosen by
// measurement (docs/scenes.md, "Which integrator").
IntegratorParams default_integrator();
// The named presets of DESIGN.md; nullopt for an unknown name. "generalized_alpha" comes with
// the default's rho_inf, 0.5 (generalized_alpha() gives any other).
std::optional<IntegratorParams> integrator_preset(std::string_view name);
// All preset names, for error messages and documentation.
const std::vector<std::string>& integrator_preset_names();

// Chung and Hulbert's optimal parameters for a spectral radius rho_inf in [0, 1] at infinite
// frequency: alpha_m = (2 rho - 1) / (rho + 1), alpha_f = rho / (rho + 1),
// gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2 / 4 (displacement parameter
// 2 alpha beta with alpha = 1/2).
IntegratorParams generalized_alpha(double rho_inf);
// Any weights with the parameters that follow them: gamma = 1/2 - alpha_m + alpha_f (second
// order) and 2 alpha beta = (1 - alpha_m + alpha_f)^2 / 4 with alpha = 1/2; named "custom".
// HHT-alpha is alpha_m = 0, alpha_f = -alpha_HHT; WBZ-alpha alpha_f = 0 (docs/scenes.md).
IntegratorParams generalized_alpha_weights(double alpha_m, double alpha_f);

// x_tilde = x + h v + alpha (1 - 2 beta) h^2 abar + 2 alpha beta h^2 (c_f a - c_m abar) over flat
// (3n) buffers.
void predict_x_tilde(const IntegratorParams& p, double dt, const std::vector<double>& x,
                     const std::vector<double>& v, const std::vector<double>& a,
                     const std::vector<double>& a_bar, std::vector<double>& x_tilde);

// After an implicit solve: a_new = (x_new - x_tilde) / s, abar_new = c_a a_new + c_f a - c_m abar,
// v <- v + h ((1 - gamma) abar + gamma abar_new), then a <- a_new, abar <- abar_new.
void update_implicit(const IntegratorParams& p, double dt, const std::vector<double>& x_new,
                     const std::vector<double>& x_tilde, std::vector<double>& v,
                     std::vector<double>& a, std::vector<double>& a_bar);

// Takes an impulsive acceleration back out of the history after update_implicit: a -= delta and
// abar -= c_a delta, where delta (3n) is what the impulsive forces put into a_new.
void remove_impulse(const IntegratorParams& p, const std::vector<double>& delta, std::vector<double>& a,
                    std::vector<double>& a_bar);

// After an explicit step, given a_new = M^-1 f(x_new): v <- v + h((1-gamma) a + gamma a_new),
// a <- a_new (explicit schemes have alpha_m = alpha_f = 0: abar is a).
void update_explicit(const IntegratorParams& p, double dt, const std::vector<double>& a_new,
                     std::vector<double>& v, std::vector<double>& a, std::vector<double>& a_bar);

}  // namespace nexdyn
