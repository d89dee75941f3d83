// One island's linear system (see island_system.hpp).
#include "engine/sparse/island_system.hpp"

#include <limits>
#include <new>
#include <utility>

namespace nexdyn {

static_assert(IslandSystem::kDenseDofs * IslandSystem::kDenseDofs <= 65536,
              "a dense island's slots are 16-bit");

IslandSystem::IslandSystem(std::vector<int32_t> vertices) : vertices_(std::move(vertices)) {}

bool IslandSystem::update_pattern(const CscPattern& global, int64_t version, const int32_t* island_of,
                                  const int32_t* local_index, int32_t island) {
  if (version == pattern_version_) return false;
  pattern_version_ = version;
  pattern_status_ = StepStatus::ok;
  bool analyzed = false;
  if (global.nnz() > int64_t{std::numeric_limits<uint32_t>::max()}) {
    pattern_status_ = StepStatus::linear_solver_failed;
    error_ = "the Newton matrix has " + std::to_string(global.nnz()) +
             " stored entries, more than the 2^32 an island's value table can index";
  } else {
    try {
      analyzed = build_tables(global, island_of, local_index, island);
    } catch (const std::bad_alloc&) {
      pattern_status_ = StepStatus::linear_solver_failed;
      error_ = "out of memory building the tables of an island of " + std::to_string(num_dofs()) + " DOFs";
    }
  }
  if (pattern_status_ != StepStatus::ok) {
    // Half-built tables, or no analysis for the ones kept: forget them, so that the next call
    // builds everything again whatever its version.
    pattern_version_ = -1;
    value_source_.clear();
    dense_slot_.clear();
    col_ptr_.clear();
    row_idx_.clear();
  }
  return analyzed;
}

bool IslandSystem::build_tables(const CscPattern& global, const int32_t* island_of, const int32_t* local_index,
                                int32_t island) {
  const int64_t n = num_dofs();
  const bool dense = n <= kDenseDofs;
  std::vector<int64_t> col_ptr(dense ? 0 : n + 1, 0), row_idx;
  std::vector<uint16_t> slots;
  // Exact sizes first: grown by doubling, the tables of a pile's islands held 1.5x their size.
  int64_t count = 0;
  for (int32_t v : vertices_)
    for (int d = 0; d < 3; ++d) {
      const int64_t c = 3 * int64_t{v} + d;
      for (int64_t k = global.col_ptr[c]; k < global.col_ptr[c + 1]; ++k)
        count += island_of[global.row_idx[k] / 3] == island;
    }
  value_source_.clear();
  value_source_.shrink_to_fit();
  value_source_.reserve(count);
  (dense ? slots.reserve(count) : row_idx.reserve(count));
  for (size_t l = 0; l < vertices_.size(); ++l)
    for (int d = 0; d < 3; ++d) {
      const int64_t c = 3 * int64_t{vertices_[l]} + d;
      for (int64_t k = global.col_ptr[c]; k < global.col_ptr[c + 1]; ++k) {
        const int64_t r = global.row_idx[k];
        const int32_t rv = static_cast<int32_t>(r / 3);
        // The global pattern may keep contact blocks of pairs that are no longer in contact
        // (stored zeros, contact_pattern.hpp); those between islands are dropped here.
        if (island_of[rv] != island) continue;
        const int64_t local_row = 3 * int64_t{local_index[rv]} + r % 3;
        value_source_.push_back(static_cast<uint32_t>(k));
        if (dense) slots.push_back(static_cast<uint16_t>(local_row + n * (3 * int64_t(l) + d)));
        else row_idx.push_back(local_row);
      }
      if (!dense) col_ptr[3 * l + d + 1] = static_cast<int64_t>(row_idx.size());
    }
  rhs_.resize(n);
  out_.resize(n);
  if (dense) {
    dense_.resize(n, n);
    if (slots == dense_slot_) return false;
    dense_slot_ = std::move(slots);
    return true;
  }
  values_.resize(row_idx.size());
  if (col_ptr == col_ptr_ && row_idx == row_idx_) return false;
  col_ptr_ = std::move(col_ptr);
  row_idx_ = std::move(row_idx);
  if (!cholmod_) cholmod_ = std::make_unique<CholmodSolver>(/*supernodal=*/n > kSimplicialDofs);
  pattern_status_ = cholmod_->analyze(n, col_ptr_.data(), row_idx_.data());
  if (pattern_status_ != StepStatus::ok) error_ = cholmod_->error();
  return true;
}

StepStatus IslandSystem::factorize(const double* global_values) {
  if (pattern_status_ != StepStatus::ok) return pattern_status_;  // error_ still says why
  if (cholmod_) {
    for (size_t k = 0; k < values_.size(); ++k) values_[k] = global_values[value_source_[k]];
    const StepStatus status = cholmod_->factorize(values_.data());
    if (status != StepStatus::ok) error_ = cholmod_->error();
    return status;
  }
  const int64_t n = num_dofs();
  dense_.setZero();
  double* a = dense_.data();  // column-major: slot row + n col
  for (size_t k = 0; k < value_source_.size(); ++k) a[dense_slot_[k]] = global_values[value_source_[k]];
  // In place: a second n x n copy would double the memory of the many small islands of a pile.
  const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Upper> llt(dense_);
  if (llt.info() == Eigen::Success) return StepStatus::ok;
  error_ = "matrix not positive definite (dense island of " + std::to_string(n) + " DOFs)";
  return StepStatus::factorization_failed;
}

StepStatus IslandSystem::solve(const double* global_rhs, double* global_out) {
  for (size_t l = 0; l < vertices_.size(); ++l)
    for (int d = 0; d < 3; ++d) rhs_[3 * l + d] = global_rhs[3 * int64_t{vertices_[l]} + d];
  if (cholmod_) {
    const StepStatus status = cholmod_->solve(rhs_.data(), out_.data());
    if (status != StepStatus::ok) {
      error_ = cholmod_->error();
      return status;
    }
  } else {
    Eigen::Map<Eigen::VectorXd> b(rhs_.data(), num_dofs());
    dense_.triangularView<Eigen::Upper>().transpose().solveInPlace(b);
    dense_.triangularView<Eigen::Upper>().solveInPlace(b);
    out_.swap(rhs_);
  }
  for (size_t l = 0; l < vertices_.size(); ++l)
    for (int d = 0; d < 3; ++d) global_out[3 * int64_t{vertices_[l]} + d] = out_[3 * l + d];
  return StepStatus::ok;
}

}  // namespace nexdyn
