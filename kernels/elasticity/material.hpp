// Material models and their parameters (seed 004).
//
// Young's modulus E and Poisson ratio nu are what users write; the energies use the Lame
// parameters mu = E / (2 (1 + nu)) and lambda = E nu / ((1 + nu)(1 - 2 nu)).
#pragma once

#include <cassert>
#include <cstdint>
#include <optional>
#include <string_view>
#include <type_traits>

namespace nexdyn {

enum class MaterialModel : uint8_t { linear, stvk, corotated, neohookean };

inline constexpr MaterialModel kAllMaterialModels[] = {
    MaterialModel::linear, MaterialModel::stvk, MaterialModel::corotated,
    MaterialModel::neohookean};

struct LameParameters {
  double mu = 0.0;      // shear modulus [Pa]
  double lambda = 0.0;  // first Lame parameter [Pa]
};

inline LameParameters lame_from_young_poisson(double youngs, double poisson) {
  return {youngs / (2.0 * (1.0 + poisson)),
          youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))};
}

// Scene-file names of the models.
inline std::string_view material_model_name(MaterialModel m) {
  switch (m) {
    case MaterialModel::linear: return "linear";
    case MaterialModel::stvk: return "stvk";
    case MaterialModel::corotated: return "corotated";
    case MaterialModel::neohookean: return "neohookean";
  }
  return "?";
}

inline std::optional<MaterialModel> material_model_from_name(std::string_view name) {
  for (MaterialModel m : kAllMaterialModels)
    if (material_model_name(m) == name) return m;
  return std::nullopt;
}

// Calls fn(std::integral_constant<MaterialModel, M>{}) for the runtime value m: the one switch
// that turns a material chosen at run time into a compile-time template argument. Use it outside
// loops (choose the material, then run a loop specialised for it).
template <typename Fn>
decltype(auto) with_material_model(MaterialModel m, Fn&& fn) {
  switch (m) {
    case MaterialModel::linear:
      return fn(std::integral_constant<MaterialModel, MaterialModel::linear>{});
    case MaterialModel::stvk:
      return fn(std::integral_constant<MaterialModel, MaterialModel::stvk>{});
    case MaterialModel::corotated:
      return fn(std::integral_constant<MaterialModel, MaterialModel::corotated>{});
    case MaterialModel::neohookean:
      return fn(std::integral_constant<MaterialModel, MaterialModel::neohookean>{});
  }
  assert(false && "invalid MaterialModel value");
  return fn(std::integral_constant<MaterialModel, MaterialModel::neohookean>{});
}

}  // namespace nexdyn
