// The instantiations of project_psd declared extern in psd_projection.hpp.
#include "kernels/projection/psd_projection.hpp"

namespace nexdyn {

template int project_psd<4>(Eigen::Matrix<double, 4, 4>&, double);
template int project_psd<5>(Eigen::Matrix<double, 5, 5>&, double);
template int project_psd<9>(Eigen::Matrix<double, 9, 9>&, double);
template int project_psd<12>(Eigen::Matrix<double, 12, 12>&, double);

}  // namespace nexdyn
