// Additive CCD (Li, Kaufman, Jiang 2021, Algorithm 1) over certified distance lower bounds; see
// ccd.hpp for the contract and ccd_distance.hpp for the error model.
#include "kernels/ccd/ccd.hpp"

#include "kernels/ccd/ccd_distance.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {
namespace {

template <typename T>
using PointsT = Eigen::Matrix<T, 3, 4>;
using Points = PointsT<double>;

// Fraction of the certified free interval taken per step (the paper's 0.9): the distance stays
// >= (1 - kStepFraction) d over the step, so a step can never land on a contact.
constexpr double kStepFraction = 0.9;
// The stop gap is at most this fraction of the initial distance (the paper's s = 0.1), so that a
// query starting closer than min_distance still returns a toi with positive distance.
constexpr double kGapFraction = 0.1;

// Largest absolute coordinate of the 8 points, floored at 1 so that the absolute rounding error
// of coordinates near 0 is not underestimated (subtractions of O(1) values round at eps * 1).
template <typename T>
T coordinate_scale(const PointsT<T>& x0, const PointsT<T>& x1) {
  return std::max({T(1), x0.cwiseAbs().maxCoeff(), x1.cwiseAbs().maxCoeff()});
}

// Additive CCD in precision T from t_start (0, or a time up to which the primitives are already
// known apart) for at most max_iterations steps. Columns [0, num_a) of x0/x1 are primitive A, the
// rest primitive B; `distance` returns a lower bound of the distance of the four points it is
// given.
template <int NumA, typename T, typename Distance>
bool additive_ccd(const PointsT<T>& x0, const PointsT<T>& x1, T min_distance, T t_start, T tmax,
                  int max_iterations, T& toi, Distance&& distance) {
  constexpr T eps = ccd_detail::kEpsOf<T>;
  const T scale = coordinate_scale<T>(x0, x1);
  const PointsT<T> disp = x1 - x0;
  const ccd_detail::Vec3T<T> mean = disp.rowwise().mean();
  T max_a = 0, max_b = 0;
  for (int i = 0; i < 4; ++i) {
    const T len = (disp.col(i) - mean).norm();
    if (i < NumA) max_a = std::max(max_a, len);
    else max_b = std::max(max_b, len);
  }
  // Any common offset gives a valid bound; the mean makes it small for rigid translations. The
  // factor and the eps * scale term cover the rounding of disp, mean and the norms.
  const T lp = (max_a + max_b) * (1 + 16 * eps) + 16 * eps * scale;

  T t = t_start;
  T d;
  if (t == 0) {
    d = distance(x0.col(0), x0.col(1), x0.col(2), x0.col(3), scale);
  } else {
    const PointsT<T> x = x0 + t * disp;
    d = distance(x.col(0), x.col(1), x.col(2), x.col(3), scale);
  }
  if (!(d > 0)) {  // touching (within rounding) at t_start; also catches NaN input
    toi = t;
    return true;
  }
  const T gap = std::min(min_distance, T(kGapFraction) * d);
  for (int iter = 0; iter < max_iterations; ++iter) {
    const T step = T(kStepFraction) * d / lp;
    // [t, t + step] is certified free: if it covers tmax there is no contact on [0, tmax].
    if (step >= tmax - t) return false;
    // With a zero gap the distance can settle at the rounding bound and each step shrinks below
    // an ulp of t: t stops moving. Give up at the safe t now rather than after the iteration cap
    // (measured: 40 to 80 ms per such query).
    if (t + step == t) break;
    t += step;
    const PointsT<T> x = x0 + t * disp;
    d = distance(x.col(0), x.col(1), x.col(2), x.col(3), scale);
    if (d <= gap) {
      toi = t;  // the distance on [0, t] is >= 0.1 of the previous bound > 0
      return true;
    }
  }
  toi = t;  // grazing motion: give up conservatively at a certified-safe time
  return true;
}

template <int NumA, typename Distance>
bool additive_ccd(const Points& x0, const Points& x1, double min_distance, double tmax, double& toi,
                  Distance&& distance) {
  return additive_ccd<NumA, double>(x0, x1, min_distance, 0.0, tmax, kCcdMaxIterations, toi, distance);
}

// Whether the primitives may touch: the double CCD with a gap of kTouchFirstGap of the query's
// size first; a possible contact is then continued from that CCD's toi (certified apart before
// it) in long double with gap 0, for at most kTouchRefineIterations steps.
constexpr double kTouchFirstGap = 1e-11;
constexpr int kTouchRefineIterations = 1000;

template <int NumA, typename Distance>
bool touch_ccd(const Points& x0, const Points& x1, double tmax, double& toi, Distance&& distance) {
  const Eigen::Vector3d lo = x0.rowwise().minCoeff().cwiseMin(x1.rowwise().minCoeff());
  const Eigen::Vector3d hi = x0.rowwise().maxCoeff().cwiseMax(x1.rowwise().maxCoeff());
  double t_first = 0.0;
  if (!additive_ccd<NumA, double>(x0, x1, kTouchFirstGap * (hi - lo).norm(), 0.0, tmax, kCcdMaxIterations, t_first,
                                  distance))
    return false;
  using Long = long double;
  Long t_long = 0;
  const bool touch = additive_ccd<NumA, Long>(x0.cast<Long>(), x1.cast<Long>(), Long(0), Long(t_first), Long(tmax),
                                              kTouchRefineIterations, t_long, distance);
  if (touch) {
    toi = static_cast<double>(t_long);  // rounded to nearest: take the double below if above
    if (static_cast<Long>(toi) > t_long) toi = std::nextafter(toi, 0.0);
  }
  return touch;
}

// The 4 points of a query at one time, as the columns of a Points.
Points columns(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  Points x;
  x << a, b, c, d;
  return x;
}

// The distance lower bounds, for any precision.
struct PointTriangleLower {
  template <typename V, typename T>
  T operator()(const V& p, const V& a, const V& b, const V& c, T scale) const {
    return ccd_detail::point_triangle_distance_lower<T>(p, a, b, c, scale);
  }
};
struct EdgeEdgeLower {
  template <typename V, typename T>
  T operator()(const V& a0, const V& a1, const V& b0, const V& b1, T scale) const {
    return ccd_detail::edge_edge_distance_lower<T>(a0, a1, b0, b1, scale);
  }
};

}  // namespace

bool point_triangle_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& t0_0, const Eigen::Vector3d& t1_0,
                        const Eigen::Vector3d& t2_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& t0_1,
                        const Eigen::Vector3d& t1_1, const Eigen::Vector3d& t2_1, double min_distance,
                        double tmax, double& toi) {
  return additive_ccd<1>(columns(p_0, t0_0, t1_0, t2_0), columns(p_1, t0_1, t1_1, t2_1), min_distance, tmax, toi,
                         PointTriangleLower{});
}

bool edge_edge_ccd(const Eigen::Vector3d& ea0_0, const Eigen::Vector3d& ea1_0, const Eigen::Vector3d& eb0_0,
                   const Eigen::Vector3d& eb1_0, const Eigen::Vector3d& ea0_1, const Eigen::Vector3d& ea1_1,
                   const Eigen::Vector3d& eb0_1, const Eigen::Vector3d& eb1_1, double min_distance, double tmax,
                   double& toi) {
  return additive_ccd<2>(columns(ea0_0, ea1_0, eb0_0, eb1_0), columns(ea0_1, ea1_1, eb0_1, eb1_1), min_distance, tmax,
                         toi, EdgeEdgeLower{});
}

bool point_triangle_touch_ccd(const Eigen::Vector3d& p_0, const Eigen::Vector3d& t0_0, const Eigen::Vector3d& t1_0,
                              const Eigen::Vector3d& t2_0, const Eigen::Vector3d& p_1, const Eigen::Vector3d& t0_1,
                              const Eigen::Vector3d& t1_1, const Eigen::Vector3d& t2_1, double tmax, double& toi) {
  return touch_ccd<1>(columns(p_0, t0_0, t1_0, t2_0), columns(p_1, t0_1, t1_1, t2_1), tmax, toi, PointTriangleLower{});
}

bool edge_edge_touch_ccd(const Eigen::Vector3d& ea0_0, const Eigen::Vector3d& ea1_0, const Eigen::Vector3d& eb0_0,
                         const Eigen::Vector3d& eb1_0, const Eigen::Vector3d& ea0_1, const Eigen::Vector3d& ea1_1,
                         const Eigen::Vector3d& eb0_1, const Eigen::Vector3d& eb1_1, double tmax, double& toi) {
  return touch_ccd<2>(columns(ea0_0, ea1_0, eb0_0, eb1_0), columns(ea0_1, ea1_1, eb0_1, eb1_1), tmax, toi,
                      EdgeEdgeLower{});
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
