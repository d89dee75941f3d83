// The instantiations of project_psd declared extern in psd_projection.hpp, and the dynamic-size
// symmetric eigensolver for tests and diagnostics.
#include "kernels/projection/psd_projection.hpp"

namespace nexdyn {

template int project_psd<4>(Eigen::Matrix<double, 4, 4>&, double);
template int project_psd<5>(Eigen::Matrix<double, 5, 5>&, double);
template int project_psd<6>(Eigen::Matrix<double, 6, 6>&, double);
template int project_psd<9>(Eigen::Matrix<double, 9, 9>&, double);
template int project_psd<12>(Eigen::Matrix<double, 12, 12>&, double);

SymmetricEigen symmetric_eigen(const Eigen::Ref<const Eigen::MatrixXd>& A, bool with_vectors) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(
      A, with_vectors ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  SymmetricEigen result;
  result.values = solver.eigenvalues();
  if (with_vectors) result.vectors = solver.eigenvectors();
  return result;
}

}  // namespace nexdyn
