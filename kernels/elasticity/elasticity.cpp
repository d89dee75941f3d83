// Runtime-dispatch wrappers of the element layer (elasticity.hpp): one switch on the material,
// then the specialised template. For tests and callers outside hot loops.
#include "kernels/elasticity/elasticity.hpp"

namespace nexdyn {

double energy_density(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame) {
  return with_material_model(model, [&](auto m) { return energy_density<m()>(F, lame); });
}

Eigen::Matrix3d pk1(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame) {
  return with_material_model(model, [&](auto m) { return pk1<m()>(F, lame); });
}

Matrix9d pk1_derivative(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame) {
  return with_material_model(model, [&](auto m) { return pk1_derivative<m()>(F, lame); });
}

Matrix9d pk1_derivative_projected(MaterialModel model, const Eigen::Matrix3d& F,
                                  const LameParameters& lame) {
  return with_material_model(model,
                             [&](auto m) { return pk1_derivative_projected<m()>(F, lame); });
}

double tet_energy(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                  double volume, const LameParameters& lame) {
  return with_material_model(
      model, [&](auto m) { return tet_energy<m()>(x, Dm_inv, volume, lame); });
}

double tet_energy_gradient(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                           double volume, const LameParameters& lame, Vector12d& gradient) {
  return with_material_model(model, [&](auto m) {
    return tet_energy_gradient<m()>(x, Dm_inv, volume, lame, gradient);
  });
}

double tet_energy_gradient_hessian(MaterialModel model, const Matrix34d& x,
                                   const Eigen::Matrix3d& Dm_inv, double volume,
                                   const LameParameters& lame, Vector12d& gradient,
                                   Matrix12d& hessian_projected) {
  return with_material_model(model, [&](auto m) {
    return tet_energy_gradient_hessian<m()>(x, Dm_inv, volume, lame, gradient, hessian_projected);
  });
}

Matrix12d tet_hessian_exact(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                            double volume, const LameParameters& lame) {
  return with_material_model(
      model, [&](auto m) { return tet_hessian_exact<m()>(x, Dm_inv, volume, lame); });
}

}  // namespace nexdyn
