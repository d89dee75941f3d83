// Fallback of the signed 3x3 SVD (see svd3.hpp): Eigen's two-sided Jacobi SVD, then signs fixed so
// that U and V are rotations and only the smallest singular value may be negative.
#include "kernels/elasticity/svd3.hpp"

// GCC 12 cannot see that JacobiSVD fills every singular value and warns about reading them.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <Eigen/LU>
#include <Eigen/SVD>

#include <limits>

namespace nexdyn {

void svd3_jacobi(const Eigen::Matrix3d& F, Svd3& out) {
  if (!F.allFinite()) {
    // JacobiSVD's sweep loop is driven by comparisons that NaN makes meaningless.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    out.U.setConstant(nan);
    out.sigma.setConstant(nan);
    out.V.setConstant(nan);
    return;
  }
  // Square input: the QR preconditioner (for tall matrices) is not needed.
  Eigen::JacobiSVD<Eigen::Matrix3d, Eigen::NoQRPreconditioner> svd(
      F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  out.U = svd.matrixU();
  out.V = svd.matrixV();
  out.sigma = svd.singularValues();  // descending, >= 0
  // A reflection in U or V is moved into the smallest singular value: negating the last column
  // of U (or V) and sigma_2 together leaves U diag(sigma) V^T unchanged.
  if (out.U.determinant() < 0.0) {
    out.U.col(2) = -out.U.col(2);
    out.sigma[2] = -out.sigma[2];
  }
  if (out.V.determinant() < 0.0) {
    out.V.col(2) = -out.V.col(2);
    out.sigma[2] = -out.sigma[2];
  }
}

}  // namespace nexdyn

#pragma GCC diagnostic pop
