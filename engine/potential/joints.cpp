// Augmented-Lagrangian joints (see joints.hpp).
#include "engine/potential/joints.hpp"

#include <algorithm>

namespace nexdyn {

namespace {

// Coupling groups of a joint: local term indices of each group of 4.
// Pin: its tet. Ball: each tet, then pairs of corners across the two (cross blocks only).
constexpr int kPinGroups = 1;
constexpr int kBallGroups = 6;
constexpr int kBallGroupTerms[kBallGroups][4] = {
    {0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 4, 5}, {0, 1, 6, 7}, {2, 3, 4, 5}, {2, 3, 6, 7}};

int group_count(const Joint& joint) { return joint.type == JointType::pin ? kPinGroups : kBallGroups; }

const int (&group_terms(const Joint& joint, int g))[4] {
  static constexpr int kPin[4] = {0, 1, 2, 3};
  return joint.type == JointType::pin ? kPin : kBallGroupTerms[g];
}

// A cross group (ball groups 2..5) holds only the blocks between its two sides: the blocks within
// one side are already in the tets' own groups.
bool cross_group(const Joint& joint, int g) { return joint.type == JointType::ball && g >= 2; }

}  // namespace

JointSet::JointSet(const Model& model, std::vector<double>& multipliers)
    : joints_(model.joints), mass_(model.mass), stiffness_(model.joints.size(), 0.0),
      multiplier_(multipliers) {
  multiplier_.assign(3 * joints_.size(), 0.0);
  for (const Joint& joint : joints_)
    for (int g = 0; g < group_count(joint); ++g)
      for (int t : group_terms(joint, g)) groups_.push_back(joint.vertex[t]);
}

void JointSet::write_slabs(double* slabs) const {
  int64_t group = 0;
  for (size_t j = 0; j < joints_.size(); ++j) {
    const Joint& joint = joints_[j];
    for (int g = 0; g < group_count(joint); ++g, ++group) {
      const int(&terms)[4] = group_terms(joint, g);
      Eigen::Map<Eigen::Matrix<double, 12, 12>> slab(slabs + 144 * group);
      slab.setZero();
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const bool same_side = (terms[a] < 4) == (terms[b] < 4);
          if (cross_group(joint, g) && same_side) continue;
          const double value =
              weight_ * stiffness_[j] * joint.coefficient[terms[a]] * joint.coefficient[terms[b]];
          for (int r = 0; r < 3; ++r) slab(3 * a + r, 3 * b + r) = value;
        }
    }
  }
}

void JointSet::set_stiffness(double weight, double scale, double ratio, double stiffening, double* slabs) {
  weight_ = weight;
  for (size_t j = 0; j < joints_.size(); ++j) {
    double mass = 0.0;
    for (int k = 0; k < joints_[j].count; ++k) mass += mass_[joints_[j].vertex[k]];
    stiffness_[j] = ratio * mass / scale * stiffening;
  }
  write_slabs(slabs);
}

Eigen::Vector3d JointSet::violation(const double* x, int64_t j) const {
  const Joint& joint = joints_[j];
  Eigen::Vector3d c = joint.offset;
  for (int k = 0; k < joint.count; ++k)
    c += joint.coefficient[k] * Eigen::Vector3d::Map(x + 3 * int64_t{joint.vertex[k]});
  return c;
}

double JointSet::max_violation(const double* x) const {
  double worst = 0.0;
  for (int64_t j = 0; j < size(); ++j) worst = std::max(worst, violation(x, j).norm());
  return worst;
}

double JointSet::energy(const double* x) const {
  double sum = 0.0;
  for (int64_t j = 0; j < size(); ++j) {
    const Eigen::Vector3d c = violation(x, j);
    sum += 0.5 * stiffness_[j] * c.squaredNorm() - multiplier(j).dot(c);
  }
  return weight_ * sum;
}

void JointSet::group_energy(const double* x, const int32_t* group_of_vertex, double* total) const {
  for (int64_t j = 0; j < size(); ++j) {
    const Joint& joint = joints_[j];
    int32_t g = -1;
    for (int k = 0; k < joint.count && g < 0; ++k) g = group_of_vertex[joint.vertex[k]];
    if (g < 0) continue;
    const Eigen::Vector3d c = violation(x, j);
    total[g] += weight_ * (0.5 * stiffness_[j] * c.squaredNorm() - multiplier(j).dot(c));
  }
}

Eigen::Vector3d JointSet::force(const double* x, int64_t j) const {
  return multiplier(j) - stiffness_[j] * violation(x, j);
}

void JointSet::add_gradient(const double* x, double* grad, double scale) const {
  for (int64_t j = 0; j < size(); ++j) {
    const Eigen::Vector3d f = -(scale * weight_) * force(x, j);  // scale w (k c - lambda)
    const Joint& joint = joints_[j];
    for (int k = 0; k < joint.count; ++k)
      Eigen::Vector3d::Map(grad + 3 * int64_t{joint.vertex[k]}) += joint.coefficient[k] * f;
  }
}

void JointSet::update_multipliers(const double* x) {
  for (int64_t j = 0; j < size(); ++j) multiplier(j) = force(x, j);
}

void JointSet::apply(const double* field, double* out) const {
  for (int64_t j = 0; j < size(); ++j) {
    const Joint& joint = joints_[j];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < joint.count; ++k)
      sum += joint.coefficient[k] * Eigen::Vector3d::Map(field + 3 * int64_t{joint.vertex[k]});
    Eigen::Vector3d::Map(out + 3 * j) = sum;
  }
}

void JointSet::apply_transpose(const double* per_joint, double* out) const {
  for (int64_t j = 0; j < size(); ++j) {
    const Joint& joint = joints_[j];
    const Eigen::Vector3d value = Eigen::Vector3d::Map(per_joint + 3 * j);
    for (int k = 0; k < joint.count; ++k)
      Eigen::Vector3d::Map(out + 3 * int64_t{joint.vertex[k]}) += joint.coefficient[k] * value;
  }
}

}  // namespace nexdyn
