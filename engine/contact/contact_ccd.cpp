// The collision-free step of the barrier potential: the swept candidate search and the
// conservative CCD over its pairs (BarrierPotential::sweep, group_max_steps and max_step; see
// barrier_potential.hpp). The narrow-phase queries are kernels/ccd.
#include "engine/contact/barrier_potential.hpp"

#include "engine/contact/pair_geometry.hpp"
#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"
#include "kernels/ccd/ccd.hpp"
#include "kernels/distance/point_edge_distance.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace nexdyn {

using pair_geometry::box_gap_squared;
using pair_geometry::candidate_vertices;
using pair_geometry::kFarMargin;
using pair_geometry::kPairGrain;
using pair_geometry::point;

namespace {

// A CCD step stops at a distance of at most this fraction of dhat (and of the starting
// distance): far enough from 0 that the barrier stays finite, close enough not to stall.
constexpr double kCcdGapFraction = 0.1;

// The skin of a masked sweep, in dhat: how far an affine body's vertex may later stray from its
// swept segment and still be covered by the sweep's pairs (BarrierPotential::sweep).
constexpr double kSweepSkin = 0.5;

// skin_radius_ of an affine body's nodes (p and the columns of A): points of no pair, so their
// motion never needs a search.
constexpr double kNoPoint = std::numeric_limits<double>::infinity();

}  // namespace

double BarrierPotential::max_step(const double* x, const double* p) {
  if (solved_.empty() || !incremental_search(x, p)) sweep(x, p);
  double alpha = 1.0;
  group_max_steps(x, nullptr, &alpha);
  return alpha;
}

void BarrierPotential::move_sweep_end(const double* x, const double* p) {
  parallel_for(model_.num_dofs(), [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x1_[i] = x[i] + p[i];
  }, 8192);
}

bool BarrierPotential::covered_by_last_sweep(const double* x, const double* p, const uint8_t* moving,
                                             const double* pad) const {
  if (!skin_valid_) return false;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    if (!moving[v] || skin_radius_[v] == kNoPoint) continue;
    const double radius = skin_radius_[v] - (pad ? pad[v] : 0.0);
    if (skin_radius_[v] < 0.0 || radius < 0.0) return false;  // (< 0: it did not move in that search)
    // The capsule is convex: both ends of the new segment inside it (shrunk by the new pad) put
    // the padded segment inside it.
    const Eigen::Vector3d a = point(skin_from_.data(), v), b = point(skin_to_.data(), v);
    const Eigen::Vector3d q0 = point(x, v), q1 = q0 + point(p, v);
    if (point_edge_distance(q0, a, b) > radius * radius || point_edge_distance(q1, a, b) > radius * radius)
      return false;
  }
  return true;
}

void BarrierPotential::sweep(const double* x, const double* p, const uint8_t* moving, const double* pad) {
  ProfileScope scope(profile_, StepPhase::ccd);  // the candidate search inside is broad phase
  const int64_t n = model_.num_dofs();
  move_sweep_end(x, p);
  if (!moving) return find_candidates(x, x1_.data());  // (no pads: only the solver's sweeps pass them)
  ProfileScope broad(profile_, StepPhase::broad_phase);
  static_search_ = false;
  // The kept pairs cover the still vertices where they are, the fresh ones the moving ones at x.
  if (covers_) cover_x_.assign(x, x + n);
  // A motion inside the last masked search's capsules: its pairs are all in the list already. A
  // pair that comes within dhat along it has its vertices inside their capsules all the while,
  // so its primitives' boxes, widened by the capsules' radii, overlapped in that search (and a
  // vertex-plane pair's distance there was at most its least inside the capsule).
  if (covered_by_last_sweep(x, p, moving, pad)) return;
  // The affine bodies' moving vertices are widened by the skin (a tet body's are not: its own
  // pairs are searched in its co-moving frame, whose capsules this does not track).
  const int32_t nv = model_.num_vertices;
  const double skin = kSweepSkin * dhat_;
  skinned_pad_.resize(nv);
  skin_from_.assign(x, x + n);
  skin_to_.assign(x1_.begin(), x1_.end());
  skin_radius_.resize(nv);
  for (int32_t v = 0; v < nv; ++v) {
    const double own = pad ? pad[v] : 0.0;
    const bool skinned = moving[v] && model_.follows_body(v) && model_.dirichlet[v] < 0;
    skinned_pad_[v] = skinned ? own + skin : own;
    const bool node = !model_.follows.empty() && (model_.follows[v] == Model::kCentreNode || model_.axis_node(v));
    skin_radius_[v] = node ? kNoPoint : skinned ? own + skin : -1.0;
  }
  skin_valid_ = true;
  // Pairs of vertices that stay put keep their candidates: none of them moved since the last
  // search, and that search covered where they are now. Only pairs with a moving vertex are
  // searched again; the two sets are disjoint, and merging keeps the lists sorted.
  find_contact_candidates(model_, x, x1_.data(), 0.5 * dhat_, fresh_, moving, skinned_pad_.data());
  auto still = [&](const PairVertices& vertices) {
    for (int32_t v : vertices)
      if (v >= 0 && moving[v]) return false;
    return true;
  };
  // Each list becomes its kept pairs merged with the fresh ones; origin_ records where each
  // pair of the new lists was in the old ones (-1: new), so that the active set's cache entries
  // follow their pairs: the kept ones, and the fresh ones that the old list held too (a moving
  // vertex's pairs found again, most of them), whose distances at x the CCD then knows.
  const int64_t old_size = candidates_.size();
  origin_.clear();
  int64_t old_base = 0;
  for_each_pair_list(model_, [&](auto member, auto&& vertices_of) {
    std::vector<IndexPair>& list = candidates_.*member;
    const std::vector<IndexPair>& fresh = fresh_.*member;
    kept_.clear();
    kept_index_.clear();
    redone_.clear();
    redone_index_.clear();
    for (size_t i = 0; i < list.size(); ++i) {
      const bool keep = still(vertices_of(list[i]));
      (keep ? kept_ : redone_).push_back(list[i]);
      (keep ? kept_index_ : redone_index_).push_back(old_base + static_cast<int64_t>(i));
    }
    old_base += static_cast<int64_t>(list.size());
    list.resize(kept_.size() + fresh.size());
    size_t a = 0, b = 0, r = 0;
    for (IndexPair& out : list) {
      if (b == fresh.size() || (a < kept_.size() && kept_[a] < fresh[b])) {
        origin_.push_back(kept_index_[a]);
        out = kept_[a++];
      } else {
        while (r < redone_.size() && redone_[r] < fresh[b]) ++r;
        origin_.push_back(r < redone_.size() && redone_[r] == fresh[b] ? redone_index_[r] : -1);
        out = fresh[b++];
      }
    }
  });
  active_.carry_pairs(old_size, origin_);
}

namespace {

// The distinct groups of a pair's moving vertices, in vertex order, padded with -1 (all -1: none
// of its vertices moves). Without a group_of_vertex every moving pair is in group 0.
std::array<int32_t, 4> groups_of(const PairVertices& vertices, const int32_t* group_of_vertex) {
  std::array<int32_t, 4> groups = {-1, -1, -1, -1};
  if (!group_of_vertex) {
    groups[0] = 0;
    return groups;
  }
  int count = 0;
  for (int32_t v : vertices) {
    if (v < 0 || group_of_vertex[v] < 0) continue;
    const int32_t g = group_of_vertex[v];
    if (std::find(groups.begin(), groups.begin() + count, g) == groups.begin() + count) groups[count++] = g;
  }
  return groups;
}

// Whether a pair whose distance at x is at least `bound` (> 0; else unknown) certainly stays
// apart on [0, tmax] of the motion x -> y, so that the CCD need not run: its closing reach bounds
// how far the distance can shrink. Asked to close no more than 80% of it, the distance stays
// above 0.2 d, above the CCD's gap (at most 0.1 d), and the CCD would find nothing too: the
// margin covers the rounding of both tests, so the answer is the CCD's own, bit for bit.
bool stays_apart(const PairVertices& s, int split, const double* x, const double* y, double tmax, double bound) {
  return bound > 0.0 && pair_geometry::closing_reach(s, split, x, y) * tmax <= 0.8 * bound;
}

}  // namespace

bool BarrierPotential::pair_ccd(int64_t i, const double* x, const double* y, double tmax, double& toi,
                                 bool* cleared) const {
  const ContactCandidates& c = candidates_;
  // "No impact" from the box or the distance test alone, told to the caller who asked.
  if (cleared) *cleared = false;
  auto apart = [cleared] {
    if (cleared) *cleared = true;
    return false;
  };
  const double min_distance = kCcdGapFraction * dhat_;
  // A pair whose paths' boxes stay farther apart than the CCD's gap never comes that close: the
  // CCD would find nothing (pair_geometry.hpp).
  const double far_gap2 = (kFarMargin * min_distance) * (kFarMargin * min_distance);
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  if (i < nvt) {
    const PairVertices s = vertex_triangle_vertices(model_, c.vertex_triangle[i]);
    if (box_gap_squared(x, y, s, 1) > far_gap2) return apart();
    if (stays_apart(s, 1, x, y, tmax, active_.distance_bound(i, s, 1, cache_motion_.data()))) return apart();
    return point_triangle_ccd(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3]),
                              point(y, s[0]), point(y, s[1]), point(y, s[2]), point(y, s[3]),
                              min_distance, tmax, toi);
  }
  if (i < nvt + nee) {
    const PairVertices s = edge_edge_vertices(model_, c.edge_edge[i - nvt]);
    if (box_gap_squared(x, y, s, 2) > far_gap2) return apart();
    if (stays_apart(s, 2, x, y, tmax, active_.distance_bound(i, s, 2, cache_motion_.data()))) return apart();
    return edge_edge_ccd(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3]),
                         point(y, s[0]), point(y, s[1]), point(y, s[2]), point(y, s[3]),
                         min_distance, tmax, toi);
  }
  const IndexPair& pr = c.vertex_plane[i - nvt - nee];
  const ObstaclePlane& plane = model_.obstacle_planes[pr.second];
  return point_plane_ccd(point(x, pr.first), point(y, pr.first), plane.point, plane.normal, min_distance, tmax,
                         toi);
}

bool BarrierPotential::bodies_stay_apart(int64_t i) const {
  // Each side of the pair moves no more than its body's largest motion, and was no more than its
  // body's largest motion since the cache from where the cache saw it: both bounds are the
  // pair's own (closing_reach, distance_bound) or larger, bit for bit, so a pair they clear for
  // the whole motion (tmax 1) pair_ccd clears too, for any tmax.
  const double bound = active_.body_distance_bound(i, body_cache_motion_.data());
  if (!(bound > 0.0)) return false;
  const ContactActiveSet::SideBodies& b = active_.side_bodies(i);
  return body_reach_[b.first] + body_reach_[b.second] <= 0.8 * bound;
}

void BarrierPotential::earliest_impacts(const double* x, const int32_t* group_of_vertex, double* alpha,
                                        bool set_links_aside) {
  const double* y = x1_.data();
  const ContactCandidates& c = candidates_;
  // Per body, the bounds of bodies_stay_apart: the largest motion since the cache, and the
  // largest of x -> y (squared, then the root, as closing_reach takes it) of its point vertices.
  const int64_t count = c.size();
  active_.body_motion_since_cache(cache_motion_, body_cache_motion_);
  body_reach_.resize(model_.bodies.size());
  parallel_for(count > 0 ? static_cast<int64_t>(model_.bodies.size()) : 0, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const BodyRange& body = model_.bodies[k];
      double reach2 = 0.0;
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
        if (!model_.follows.empty() && model_.follows[v] < Model::kOwnNode) continue;  // (p or a column of A)
        const double* a = x + 3 * int64_t{v};
        const double* b = y + 3 * int64_t{v};
        const double dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
        const double step2 = dx * dx + dy * dy + dz * dz;
        reach2 = std::isnan(step2) ? std::numeric_limits<double>::infinity() : std::max(reach2, step2);
      }
      body_reach_[k] = std::sqrt(reach2);
    }
  }, 16);
  // Earliest time of impact per group, per fixed chunk of pairs. Within a chunk, a run of pairs
  // of one group passes its running minimum as tmax to cut work short. Each run leaves one
  // (group, time) result, and the results are combined in chunk order: the same on any thread
  // count. A pair's group is that of its first moving vertex; with set_links_aside, a pair whose
  // moving vertices lie in several groups goes to links_ instead (in pair order).
  const int64_t chunks = (count + kPairGrain - 1) / kPairGrain;
  run_minima_.resize(std::max<size_t>(run_minima_.size(), chunks));
  link_chunks_.resize(std::max<size_t>(link_chunks_.size(), chunks));
  parallel_for(chunks, [&](int64_t cb, int64_t ce) {
    for (int64_t k = cb; k < ce; ++k) {
      stop_point();
      std::vector<std::pair<int32_t, double>>& runs = run_minima_[k];
      runs.clear();
      link_chunks_[k].clear();
      for (int64_t i = k * kPairGrain; i < std::min(count, (k + 1) * kPairGrain); ++i) {
        if (bodies_stay_apart(i)) continue;  // (no impact: in no run and no link)
        const std::array<int32_t, 4> groups = groups_of(candidate_vertices(model_, c, i), group_of_vertex);
        if (groups[0] < 0) continue;
        if (set_links_aside && groups[1] >= 0) {
          link_chunks_[k].push_back(i);
          continue;
        }
        if (runs.empty() || runs.back().first != groups[0]) runs.emplace_back(groups[0], 1.0);
        double toi = 1.0;
        if (pair_ccd(i, x, y, runs.back().second, toi)) runs.back().second = std::min(runs.back().second, toi);
      }
    }
  }, 1);
  links_.clear();
  for (int64_t k = 0; k < chunks; ++k) {
    for (const auto& [g, t] : run_minima_[k]) alpha[g] = std::min(alpha[g], t);
    links_.insert(links_.end(), link_chunks_[k].begin(), link_chunks_[k].end());
  }
}

void BarrierPotential::group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha) {
  ProfileScope scope(profile_, StepPhase::ccd);
  active_.motion_since_cache(x, cache_motion_);
  earliest_impacts(x, group_of_vertex, alpha, false);  // (every pair in one group: the caller's promise)
}

void BarrierPotential::linked_max_steps(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                                        double* alpha) {
  ProfileScope scope(profile_, StepPhase::ccd);
  const double* y = x1_.data();
  const ContactCandidates& c = candidates_;
  // 1. Each group's own pairs (their moving vertices all in it); the pairs that link groups are
  // set aside.
  active_.motion_since_cache(x, cache_motion_);
  earliest_impacts(x, group_of_vertex, alpha, true);
  if (links_.empty()) return;
  const int64_t num_links = static_cast<int64_t>(links_.size());
  link_toi_.resize(num_links);
  link_cleared_.resize(num_links);
  auto link_groups = [&](int64_t k) { return groups_of(candidate_vertices(model_, c, links_[k]), group_of_vertex); };

  // 2. The links along the whole motion, each lowering all its groups. An impact later than the
  // largest cap among them would lower none, so that is as far as each is checked.
  parallel_for(num_links, [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) {
      double tmax = 0.0;
      for (int32_t g : link_groups(k))
        if (g >= 0) tmax = std::max(tmax, alpha[g]);
      double toi = 1.0;
      bool cleared = false;
      link_toi_[k] = pair_ccd(links_[k], x, y, tmax, toi, &cleared) ? toi : 1.0;
      link_cleared_[k] = cleared;
    }
  }, kPairGrain);
  for (int64_t k = 0; k < num_links; ++k)
    for (int32_t g : link_groups(k))
      if (g >= 0) alpha[g] = std::min(alpha[g], link_toi_[k]);

  // 3. The groups now move by different fractions of their motions. Each round checks, along the
  // motion the current fractions give (vertex v of group g ends at x + alpha[g] (x1 - x)), the
  // links whose groups take different fractions; a link whose groups all take one fraction moves
  // along a part of its swept path that step 2 cleared (every one of its groups' caps is at most
  // its time of impact). Each link that comes closer than the CCD's gap lowers its groups to the
  // smallest fraction among them. Fractions only fall, to values already present, so the rounds
  // end; at worst every group of a linked set takes the set's smallest cap. A link that step 2's
  // box or distance test cleared stays clear: each of its vertices now moves along a part of the
  // path step 2 saw (its group's fraction is at most that step's tmax), so the boxes hold and the
  // closing reach is no larger; only the others are checked.
  open_links_.clear();
  for (int64_t k = 0; k < num_links; ++k)
    if (!link_cleared_[k]) open_links_.push_back(k);
  const int64_t num_open = static_cast<int64_t>(open_links_.size());
  open_groups_.resize(num_open);
  for (int64_t o = 0; o < num_open; ++o) open_groups_[o] = link_groups(open_links_[o]);
  // A link whose groups kept their fractions since it was last checked moves as it did then: only
  // links with a group lowered in the last round are checked again.
  lowered_.assign(num_groups, 1);
  settled_.assign(alpha, alpha + num_groups);
  link_hits_.resize(num_open);
  const int64_t n = model_.num_dofs();
  scaled_end_.resize(n);
  for (;;) {
    parallel_for(n, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) {
        const int32_t g = group_of_vertex[i / 3];
        scaled_end_[i] = g < 0 ? x[i] : x[i] + alpha[g] * (y[i] - x[i]);
      }
    }, 8192);
    parallel_for(num_open, [&](int64_t b, int64_t e) {
      for (int64_t o = b; o < e; ++o) {
        link_hits_[o] = 0;
        const std::array<int32_t, 4>& groups = open_groups_[o];
        bool same = true, lowered = false;
        for (int32_t g : groups) {
          same = same && (g < 0 || alpha[g] == alpha[groups[0]]);
          lowered = lowered || (g >= 0 && lowered_[g]);
        }
        double toi = 1.0;
        if (!same && lowered) link_hits_[o] = pair_ccd(links_[open_links_[o]], x, scaled_end_.data(), 1.0, toi);
      }
    }, kPairGrain);
    bool lowered = false;
    for (int64_t o = 0; o < num_open; ++o) {
      if (!link_hits_[o]) continue;
      const std::array<int32_t, 4>& groups = open_groups_[o];
      double smallest = 1.0;
      for (int32_t g : groups)
        if (g >= 0) smallest = std::min(smallest, alpha[g]);
      for (int32_t g : groups)
        if (g >= 0 && smallest < settled_[g]) settled_[g] = smallest, lowered = true;
    }
    for (int32_t g = 0; g < num_groups; ++g) lowered_[g] = settled_[g] != alpha[g];
    if (!lowered) return;
    std::copy(settled_.begin(), settled_.end(), alpha);
  }
}

}  // namespace nexdyn
