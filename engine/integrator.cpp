// Presets and flat-buffer update kernels of the (alpha, beta, gamma) integrator family.
#include "engine/integrator.hpp"

#include "engine/parallel.hpp"

namespace nexdyn {

namespace {
const std::vector<IntegratorParams>& presets() {
  static const std::vector<IntegratorParams> kPresets = {
      {"implicit_euler", 1.0, 0.5, 1.0, false},
      {"newmark", 0.5, 0.25, 0.5, false},
      {"newmark_linear", 0.5, 1.0 / 6.0, 0.5, false},
      {"fox_goodwin", 0.5, 1.0 / 12.0, 0.5, false},
      {"central_difference", 0.5, 0.0, 0.5, false},
      {"symplectic_euler", 1.0, 0.0, 0.0, false},
      {"static", 0.0, 0.0, 0.0, true},
  };
  return kPresets;
}
}  // namespace

std::optional<IntegratorParams> integrator_preset(std::string_view name) {
  for (const IntegratorParams& p : presets())
    if (p.name == name) return p;
  return std::nullopt;
}

const std::vector<std::string>& integrator_preset_names() {
  static const std::vector<std::string> kNames = [] {
    std::vector<std::string> names;
    for (const IntegratorParams& p : presets()) names.push_back(p.name);
    return names;
  }();
  return kNames;
}

void predict_x_tilde(const IntegratorParams& p, double dt, const std::vector<double>& x,
                     const std::vector<double>& v, const std::vector<double>& a,
                     std::vector<double>& x_tilde) {
  x_tilde.resize(x.size());
  const double c = p.alpha * (1.0 - 2.0 * p.beta) * dt * dt;
  parallel_for(static_cast<int64_t>(x.size()), [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) x_tilde[i] = x[i] + dt * v[i] + c * a[i];
  }, 4096);
}

void update_implicit(const IntegratorParams& p, double dt, const std::vector<double>& x_new,
                     const std::vector<double>& x_tilde, std::vector<double>& v,
                     std::vector<double>& a) {
  const double inv_s = 1.0 / p.potential_scale(dt);
  parallel_for(static_cast<int64_t>(x_new.size()), [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const double a_new = (x_new[i] - x_tilde[i]) * inv_s;
      v[i] += dt * ((1.0 - p.gamma) * a[i] + p.gamma * a_new);
      a[i] = a_new;
    }
  }, 4096);
}

void update_explicit(const IntegratorParams& p, double dt, const std::vector<double>& a_new,
                     std::vector<double>& v, std::vector<double>& a) {
  parallel_for(static_cast<int64_t>(a_new.size()), [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      v[i] += dt * ((1.0 - p.gamma) * a[i] + p.gamma * a_new[i]);
      a[i] = a_new[i];
    }
  }, 4096);
}

}  // namespace nexdyn
