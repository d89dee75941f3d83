// Terms of a step's energy balance (see energy_balance.hpp). Serial sums in vertex order: the
// columns do not depend on the number of threads, and they cost a pass over the vertices.
#include "engine/energy_balance.hpp"

namespace nexdyn {

double held_kinetic_energy(const Model& model, const std::vector<double>& v) {
  double kinetic = 0.0;
  for (int32_t i = 0; i < model.num_vertices; ++i) {
    if (model.dirichlet[i] < 0) continue;
    const double* vi = &v[3 * int64_t{i}];
    kinetic += 0.5 * model.mass[i] * (vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2]);
  }
  return kinetic;
}

bool held_vertices_move(const Model& model, const std::vector<double>& x_old, const std::vector<double>& x_new) {
  for (int32_t i = 0; i < model.num_vertices; ++i) {
    if (model.dirichlet[i] < 0) continue;
    for (int d = 0; d < 3; ++d)
      if (x_old[3 * int64_t{i} + d] != x_new[3 * int64_t{i} + d]) return true;
  }
  return false;
}

double boundary_work(const Model& model, const std::vector<double>& x_old, const std::vector<double>& x_new,
                     const std::vector<double>& elastic_gradient_old,
                     const std::vector<double>& elastic_gradient_new,
                     const std::vector<const std::vector<double>*>& end_forces) {
  double work = 0.0;
  for (int32_t i = 0; i < model.num_vertices; ++i) {
    if (model.dirichlet[i] < 0) continue;
    for (int d = 0; d < 3; ++d) {
      const int64_t k = 3 * int64_t{i} + d;
      const double dx = x_new[k] - x_old[k];
      if (dx == 0.0) continue;
      double force = -model.mass[i] * model.gravity[d] + 0.5 * (elastic_gradient_old[k] + elastic_gradient_new[k]);
      for (const std::vector<double>* f : end_forces)
        if (!f->empty()) force -= (*f)[k];
      work += force * dx;
    }
  }
  return work;
}

double friction_dissipation(const std::vector<double>& x_old, const std::vector<double>& x_new,
                            const std::vector<double>& friction_force) {
  double dissipated = 0.0;
  for (size_t k = 0; k < friction_force.size(); ++k) dissipated -= friction_force[k] * (x_new[k] - x_old[k]);
  return dissipated;
}

}  // namespace nexdyn
