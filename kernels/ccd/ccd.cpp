// Additive CCD (Li, Kaufman, Jiang 2021, Algorithm 1) over certified distance lower bounds; see
// ccd.hpp for the contract and ccd_distance.hpp for the error model.
#include "kernels/ccd/ccd.hpp"

#include "kernels/ccd/ccd_distance.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {
namespace {

using ccd_detail::Vec3;
using Points = Eigen::Matrix<double, 3, 4>;

// Fraction of the certified free interval taken per step (the paper's 0.9): the distance stays
// >= (1 - kStepFraction) d over the step, so a step can never land on a contact.
constexpr double kStepFraction = 0.9;
// The stop gap is at most this fraction of the initial distance (the paper's s = 0.1), so that a
// query starting closer than min_distance still returns a toi with positive distance.
constexpr double kGapFraction = 0.1;

// Largest absolute coordinate of the 8 points, floored at 1 so that the absolute rounding error
// of coordinates near 0 is not underestimated (subtractions of O(1) values round at eps * 1).
double coordinate_scale(const Points& x0, const Points& x1) {
  return std::max({1.0, x0.cwiseAbs().maxCoeff(), x1.cwiseAbs().maxCoeff()});
}

// Additive CCD. Columns [0, num_a) of x0/x1 are primitive A, the rest primitive B; `distance`
// returns a lower bound of the distance of the four points it is given.
template <int NumA, typename Distance>
bool additive_ccd(const Points& x0, const Points& x1, double min_distance, double tmax, double& toi,
                  Distance&& distance) {
  const double scale = coordinate_scale(x0, x1);
  const Points disp = x1 - x0;
  const Vec3 mean = disp.rowwise().mean();
  double max_a = 0.0, max_b = 0.0;
  for (int i = 0; i < 4; ++i) {
    const double len = (disp.col(i) - mean).norm();
    if (i < NumA) max_a = std::max(max_a, len);
    else max_b = std::max(max_b, len);
  }
  // Any common offset gives a valid bound; the mean makes it small for rigid translations. The
  // factor and the eps * scale term cover the rounding of disp, mean and the norms.
  const double lp = (max_a + max_b) * (1.0 + 16.0 * ccd_detail::kEps) + 16.0 * ccd_detail::kEps * scale;

  double d = distance(x0.col(0), x0.col(1), x0.col(2), x0.col(3), scale);
  if (!(d > 0.0)) {  // touching (within rounding) at t = 0; also catches NaN input
    toi = 0.0;
    return true;
  }
  const double gap = std::min(min_distance, kGapFraction * d);
  double t = 0.0;
  for (int iter = 0; iter < kCcdMaxIterations; ++iter) {
    const double step = kStepFraction * d / lp;
    // [t, t + step] is certified free: if it covers tmax there is no contact on [0, tmax].
    if (step >= tmax - t) return false;
    // With a zero gap the distance can settle at the rounding bound and each step shrinks below
    // an ulp of t: t stops moving. Give up at the safe t now rather than after the iteration cap
    // (measured: 40 to 80 ms per such query).
    if (t + step == t) break;
    t += step;
    const Points x = x0 + t * disp;
    d = distance(x.col(0), x.col(1), x.col(2), x.col(3), scale);
    if (d <= gap) {
      toi = t;  // the distance on [0, t] is >= 0.1 of the previous bound > 0
      return true;
    }
  }
  toi = t;  // grazing motion: give up conservatively at a certified-safe time
  return true;
}

}  // namespace

bool point_triangle_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& t0_0, const Eigen::Vector3d& t1_0,
                        const Eigen::Vector3d& t2_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& t0_1,
                        const Eigen::Vector3d& t1_1, const Eigen::Vector3d& t2_1, double min_distance,
                        double tmax, double& toi) {
  Points x0, x1;
  x0 << p_0, t0_0, t1_0, t2_0;
  x1 << p_1, t0_1, t1_1, t2_1;
  return additive_ccd<1>(x0, x1, min_distance, tmax, toi,
                         [](const auto& p, const auto& a, const auto& b, const auto& c, double scale) {
                           return ccd_detail::point_triangle_distance_lower(p, a, b, c, scale);
                         });
}

bool edge_edge_ccd(const Eigen::Vector3d& ea0_0, const Eigen::Vector3d& ea1_0, const Eigen::Vector3d& eb0_0,
                   const Eigen::Vector3d& eb1_0, const Eigen::Vector3d& ea0_1, const Eigen::Vector3d& ea1_1,
                   const Eigen::Vector3d& eb0_1, const Eigen::Vector3d& eb1_1, double min_distance, double tmax,
                   double& toi) {
  Points x0, x1;
  x0 << ea0_0, ea1_0, eb0_0, eb1_0;
  x1 << ea0_1, ea1_1, eb0_1, eb1_1;
  return additive_ccd<2>(x0, x1, min_distance, tmax, toi,
                         [](const auto& a0, const auto& a1, const auto& b0, const auto& b1, double scale) {
                           return ccd_detail::edge_edge_distance_lower(a0, a1, b0, b1, scale);
                         });
}

bool point_plane_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& plane_point,
                     const Eigen::Vector3d& plane_unit_normal, double min_distance, double tmax, double& toi) {
  const double scale = std::max({1.0, p_0.cwiseAbs().maxCoeff(), p_1.cwiseAbs().maxCoeff(),
                                 plane_point.cwiseAbs().maxCoeff()});
  const double err = ccd_detail::kBaseSlack * scale;
  const double s0 = (p_0 - plane_point).dot(plane_unit_normal);
  const double s1 = (p_1 - plane_point).dot(plane_unit_normal);
  // Oriented so that the starting side is positive; both ends as lower bounds.
  const double a = std::abs(s0) - err;
  const double b = (s0 >= 0.0 ? s1 : -s1) - err;
  if (!(a > 0.0)) {
    toi = 0.0;
    return true;
  }
  const double gap = std::min(min_distance, kGapFraction * a);
  if (b > gap) return false;  // the lower bound is linear in t: it stays above the gap
  // a (1 - t) + b t = gap; a - b >= a - gap > 0.
  const double t_gap = (a - gap) / (a - b);
  if (t_gap > tmax) return false;
  toi = t_gap;
  return true;
}

}  // namespace nexdyn
