// The clamped beam the dynamics tests share: 2 m along x from -1 to +1, clamped at x = -1.
#pragma once

#include "engine/model.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn::test {

// Mean y of the free end's vertices (x = +1).
inline double tip_y(const Model& model, const std::vector<double>& x) {
  double sum = 0.0;
  int count = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.rest_positions[3 * v] > 0.999) {
      sum += x[3 * v + 1];
      ++count;
    }
  return sum / count;
}

}  // namespace nexdyn::test
