// Where a simulation's wall time goes, by phase of the step.
//
// Code marks a phase with a ProfileScope. Times are exclusive: a scope nested in another (the
// broad phase inside the CCD step bound, say) pauses the outer one, so the phases never count
// a second twice and their sum is at most the wall time. A null profile makes scopes free, so
// the kernels can be called without one (tests, benchmarks).
//
// Phases are entered from the thread that drives the step only; the parallel work inside a
// scope is timed as the wall time of the scope.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>

namespace nexdyn {

enum class StepPhase : uint8_t {
  broad_phase,    // contact candidate searches of the solver
  ccd,            // narrow-phase CCD of the line search's step bound
  barrier,        // contact active set, derivatives and their merge into the Newton matrix
  friction,       // friction lagging (bases, normal forces) and derivatives
  elastic,        // the terms that write the elastic pattern's values: elasticity (with the
                  // joints' constant coupling slabs) and Rayleigh damping
  analysis,       // CHOLMOD symbolic analysis (ordering), when the matrix pattern changed
  factorization,  // CHOLMOD numeric factorisation
  solve,          // triangular solves for the Newton direction
  line_search,    // energy evaluations at trial points
  measure,        // stats.csv columns (energies, contact summary)
  count
};

// Names for the summary line, and the timings.csv columns (milliseconds).
inline constexpr std::array<const char*, static_cast<size_t>(StepPhase::count)> kStepPhaseNames = {
    "broad phase", "CCD", "barrier", "friction", "elastic", "analysis",
    "factorisation", "solve", "line search", "measure"};
inline constexpr std::array<const char*, static_cast<size_t>(StepPhase::count)> kStepPhaseColumns = {
    "broad_phase_ms", "ccd_ms", "barrier_ms", "friction_ms", "elastic_ms", "analysis_ms",
    "factorisation_ms", "solve_ms", "line_search_ms", "measure_ms"};

class StepProfile {
 public:
  using Clock = std::chrono::steady_clock;

  void enter(StepPhase phase) {
    const Clock::time_point now = Clock::now();
    if (depth_ > 0) charge(now);
    stack_[depth_++] = phase;  // nesting is shallow (at most 3 in the step); see kMaxDepth
    since_ = now;
  }
  void leave() {
    charge(Clock::now());
    --depth_;
  }
  double seconds(StepPhase phase) const { return seconds_[static_cast<size_t>(phase)]; }

 private:
  static constexpr int kMaxDepth = 8;
  void charge(Clock::time_point now) {
    seconds_[static_cast<size_t>(stack_[depth_ - 1])] += std::chrono::duration<double>(now - since_).count();
    since_ = now;
  }
  std::array<double, static_cast<size_t>(StepPhase::count)> seconds_{};
  std::array<StepPhase, kMaxDepth> stack_{};
  int depth_ = 0;
  Clock::time_point since_{};
};

class ProfileScope {
 public:
  ProfileScope(StepProfile* profile, StepPhase phase) : profile_(profile) {
    if (profile_) profile_->enter(phase);
  }
  ~ProfileScope() {
    if (profile_) profile_->leave();
  }
  ProfileScope(const ProfileScope&) = delete;
  ProfileScope& operator=(const ProfileScope&) = delete;

 private:
  StepProfile* profile_;
};

}  // namespace nexdyn
