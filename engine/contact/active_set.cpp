// The contact active set and its per-candidate cache (see active_set.hpp).
#include "engine/contact/active_set.hpp"

#include "engine/contact/pair_geometry.hpp"
#include "engine/parallel.hpp"
#include "kernels/barrier/barrier_stencils.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <algorithm>
#include <limits>

namespace nexdyn {

using pair_geometry::candidate_vertices;
using pair_geometry::point;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Candidates per chunk of the active-set passes: fixed, so the output order does not depend on
// the number of threads.
constexpr int64_t kCandidateChunk = 4096;

int64_t num_chunks(int64_t num_candidates) { return (num_candidates + kCandidateChunk - 1) / kCandidateChunk; }

// A candidate's code: 0 for an inactive pair, else 1 + its closest-feature case
// (PointTriangleCase or EdgeEdgeCase; 1 for a vertex-plane pair), plus kMollifiedCode for an
// edge-edge pair inside the mollifier's band.
constexpr uint8_t kMollifiedCode = 32;

double sq(double a) { return a * a; }

int32_t lower(int32_t a, int32_t b) { return a < b ? a : b; }
int32_t upper(int32_t a, int32_t b) { return a < b ? b : a; }

// The closest feature of active candidate i, a vertex-triangle (i < nvt) or edge-edge pair.
ClosestFeature feature_of_code(int64_t i, int64_t nvt, uint8_t code) {
  return i < nvt ? closest_feature(static_cast<PointTriangleCase>(code - 1))
                 : closest_feature(static_cast<EdgeEdgeCase>((code & ~kMollifiedCode) - 1));
}

// Point-point and point-edge features of unmollified pairs are merged; the rest are unique.
bool mergeable(int64_t i, int64_t nvt, int64_t nee, uint8_t code) {
  if (i >= nvt + nee || (code & kMollifiedCode)) return false;
  return feature_of_code(i, nvt, code).n < 4;
}

}  // namespace

int contact_stencil_size(ContactStencilKind kind) {
  switch (kind) {
    case ContactStencilKind::vertex_plane: return 1;
    case ContactStencilKind::point_point: return 2;
    case ContactStencilKind::point_edge: return 3;
    default: return 4;
  }
}

ContactActiveSet::ContactActiveSet(const Model& model, double dhat2) : model_(model), dhat2_(dhat2) {
  positions_.resize(model.num_dofs());
}

// ---- per-candidate cache ----------------------------------------------------------------------

void ContactActiveSet::carry_pairs(int64_t old_size, const std::vector<int64_t>& origin) {
  if (static_cast<int64_t>(known_.size()) != old_size) known_.assign(old_size, 0);
  distance_.resize(old_size);
  code_.resize(old_size);
  side_bodies_.resize(old_size);
  const size_t num = origin.size();
  carried_known_.resize(num);
  carried_code_.resize(num);
  carried_distance_.resize(num);
  carried_side_bodies_.resize(num);
  for (size_t i = 0; i < num; ++i) {
    const int64_t k = origin[i];
    carried_known_[i] = k < 0 ? 0 : known_[k];
    carried_code_[i] = k < 0 ? 0 : code_[k];
    carried_distance_[i] = k < 0 ? kInf : distance_[k];
    carried_side_bodies_[i] = k < 0 ? SideBodies{} : side_bodies_[k];
  }
  known_.swap(carried_known_);
  code_.swap(carried_code_);
  distance_.swap(carried_distance_);
  side_bodies_.swap(carried_side_bodies_);
}

void ContactActiveSet::refresh(const ContactCandidates& c, const double* x) {
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t num = c.size();
  if (static_cast<int64_t>(known_.size()) != num) forget_pairs(c);
  distance_.resize(num);
  code_.resize(num);
  side_bodies_.resize(num);

  // How far each vertex moved from its cached position (0: not at all; NaN when either is NaN),
  // the cache brought up to date.
  const int64_t nv = model_.num_vertices;
  vertex_motion_.resize(nv);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const double* p = x + 3 * v;
      double* q = &positions_[3 * v];
      const bool changed = !(p[0] == q[0] && p[1] == q[1] && p[2] == q[2]);
      vertex_motion_[v] = changed ? std::sqrt(sq(p[0] - q[0]) + sq(p[1] - q[1]) + sq(p[2] - q[2])) : 0.0;
      if (changed) std::copy(p, p + 3, q);
      if (changed && vertex_motion_[v] == 0.0) vertex_motion_[v] = kInf;  // (too small to square)
    }
  }, 8192);

  parallel_for(num_chunks(num), [&](int64_t cb, int64_t ce) {
    for (int64_t i = cb * kCandidateChunk; i < std::min(num, ce * kCandidateChunk); ++i) {
      const PairVertices s = candidate_vertices(model_, c, i);
      const bool primitives = i < nvt + nee;  // (else a vertex-plane pair)
      if (known_[i]) {
        // The distance shrinks by at most the largest motion of each side since it was cached
        // (a vertex-plane pair: its vertex's).
        double side[2] = {vertex_motion_[s[0]], 0.0};
        const int split = i < nvt ? 1 : 2;
        for (int k = 1; primitives && k < 4; ++k) side[k >= split] = std::max(side[k >= split], vertex_motion_[s[k]]);
        const double reach = side[0] + side[1];
        if (reach == 0.0) continue;  // (unmoved)
        // An inactive pair whose motion leaves it beyond dhat stays inactive, its distance at least
        // the old one less the motion: a lower bound, like the box gap below, with no kernel.
        const double left = std::sqrt(distance_[i]) - reach;
        if (primitives && code_[i] == 0 && left > 0.0 && left * left > pair_geometry::kFarMargin * dhat2_) {
          distance_[i] = left * left;
          continue;
        }
      }
      uint8_t code = 0;
      double d = kInf;
      const double gap2 = primitives ? pair_geometry::box_gap_squared(x, nullptr, s, i < nvt ? 1 : 2) : 0.0;
      if (gap2 > pair_geometry::kFarMargin * dhat2_) {
        d = gap2;  // beyond dhat: inactive, its distance at least this
      } else if (primitives) {
        const Eigen::Vector3d X0 = point(x, s[0]), X1 = point(x, s[1]);
        const Eigen::Vector3d X2 = point(x, s[2]), X3 = point(x, s[3]);
        if (i < nvt) {
          const PointTriangleCase pc = point_triangle_case(X0, X1, X2, X3);
          d = point_triangle_distance(X0, X1, X2, X3, pc);
          if (d < dhat2_) code = 1 + static_cast<uint8_t>(pc);
        } else {
          const EdgeEdgeCase ec = edge_edge_case(X0, X1, X2, X3);
          d = edge_edge_distance(X0, X1, X2, X3, ec);
          if (d < dhat2_) {
            code = 1 + static_cast<uint8_t>(ec);
            const double eps_x = pair_geometry::edge_edge_threshold(model_, &s[0], &s[2]);
            if (edge_edge_cross_squarednorm(X0, X1, X2, X3) < eps_x) code |= kMollifiedCode;
          }
        }
      } else {
        d = pair_geometry::vertex_plane_squared_distance(model_, x, c.vertex_plane[i - nvt - nee]);
        if (d < dhat2_) code = 1;
      }
      distance_[i] = d;
      code_[i] = code;
      known_[i] = 1;
      const std::vector<int32_t>& body = model_.vertex_body;
      side_bodies_[i] = {body[s[0]], primitives ? body[s[i < nvt ? 1 : 2]] : -1};
    }
  }, 1);
}

double ContactActiveSet::min_squared_distance(const ContactCandidates& candidates, const double* x) {
  refresh(candidates, x);
  double min_d = kInf;
  for (double d : distance_) min_d = std::min(min_d, d);
  return min_d;
}

// Each vertex's motion once, for the bounds of all candidates: read from one number a vertex
// instead of two positions. The largest of square roots is the root of the largest, so the
// bounds are closing_reach's to the bit.
void ContactActiveSet::motion_since_cache(const double* x, std::vector<double>& motion) const {
  const int64_t nv = model_.num_vertices;
  motion.resize(nv);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const double* a = &positions_[3 * v];
      const double* b = x + 3 * v;
      const double dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
      motion[v] = std::sqrt(dx * dx + dy * dy + dz * dz);  // (squared as closing_reach does)
    }
  }, 8192);
}

void ContactActiveSet::body_motion_since_cache(const std::vector<double>& motion,
                                               std::vector<double>& body_motion) const {
  body_motion.resize(model_.bodies.size());
  parallel_for(static_cast<int64_t>(model_.bodies.size()), [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const BodyRange& body = model_.bodies[k];
      double largest = 0.0;
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
        if (!model_.follows.empty() && model_.follows[v] < Model::kOwnNode) continue;  // (p or a column of A)
        largest = std::isnan(motion[v]) ? kInf : std::max(largest, motion[v]);
      }
      body_motion[k] = largest;
    }
  }, 16);
}

// ---- stencils ---------------------------------------------------------------------------------

void ContactActiveSet::build(const ContactCandidates& candidates, const double* x) {
  refresh(candidates, x);
  count_active(candidates);
  list_unique_and_features(candidates);
  merge_features();
  finish_stencils();
}

// Pass 1: count the unique and the mergeable active pairs per chunk (prefix sums).
void ContactActiveSet::count_active(const ContactCandidates& c) {
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t num = c.size();
  const int64_t chunks = num_chunks(num);
  chunk_unique_begin_.assign(chunks + 1, 0);
  chunk_feature_begin_.assign(chunks + 1, 0);
  parallel_for(chunks, [&](int64_t cb, int64_t ce) {
    for (int64_t k = cb; k < ce; ++k) {
      int64_t unique = 0, mergeable_pairs = 0;
      for (int64_t i = k * kCandidateChunk; i < std::min(num, (k + 1) * kCandidateChunk); ++i) {
        const uint8_t code = code_[i];
        if (code == 0) continue;
        if (mergeable(i, nvt, nee, code)) ++mergeable_pairs;
        else ++unique;
      }
      chunk_unique_begin_[k + 1] = unique;
      chunk_feature_begin_[k + 1] = mergeable_pairs;
    }
  }, 1);
  for (int64_t k = 0; k < chunks; ++k) {
    chunk_unique_begin_[k + 1] += chunk_unique_begin_[k];
    chunk_feature_begin_[k + 1] += chunk_feature_begin_[k];
  }
  num_active_pairs_ = chunk_unique_begin_[chunks] + chunk_feature_begin_[chunks];
}

// Pass 2: unique pairs become stencils, mergeable ones feature keys, both in candidate order.
void ContactActiveSet::list_unique_and_features(const ContactCandidates& c) {
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t num = c.size();
  const int64_t chunks = num_chunks(num);
  const int64_t num_unique = chunk_unique_begin_[chunks];
  kind_.resize(num_unique);
  vertices_.resize(4 * num_unique);
  multiplicity_.resize(num_unique);
  edge_edge_case_.resize(num_unique);
  features_.resize(chunk_feature_begin_[chunks]);
  parallel_for(chunks, [&](int64_t cb, int64_t ce) {
    for (int64_t k = cb; k < ce; ++k) {
      int64_t unique = chunk_unique_begin_[k], feature = chunk_feature_begin_[k];
      for (int64_t i = k * kCandidateChunk; i < std::min(num, (k + 1) * kCandidateChunk); ++i) {
        const uint8_t code = code_[i];
        if (code == 0) continue;
        if (i >= nvt + nee) {
          const IndexPair& pair = c.vertex_plane[i - nvt - nee];
          kind_[unique] = ContactStencilKind::vertex_plane;
          int32_t* v = &vertices_[4 * unique];
          v[0] = pair.first; v[1] = pair.second; v[2] = v[3] = -1;
          edge_edge_case_[unique] = 0;
          multiplicity_[unique++] = 1;
          continue;
        }
        const PairVertices s = candidate_vertices(model_, c, i);
        if (mergeable(i, nvt, nee, code)) {
          const ClosestFeature f = feature_of_code(i, nvt, code);
          const int32_t p = s[f.idx[0]], q = s[f.idx[1]];
          features_[feature++] = f.n == 2 ? FeatureKey{lower(p, q), upper(p, q), -1}
                                          : FeatureKey{p, lower(q, s[f.idx[2]]), upper(q, s[f.idx[2]])};
          continue;
        }
        kind_[unique] = i < nvt ? ContactStencilKind::point_triangle
                                : ((code & kMollifiedCode) ? ContactStencilKind::edge_edge_mollified
                                                           : ContactStencilKind::edge_edge);
        std::copy(s.begin(), s.end(), &vertices_[4 * unique]);
        edge_edge_case_[unique] = i < nvt ? 0 : static_cast<uint8_t>((code & ~kMollifiedCode) - 1);
        multiplicity_[unique++] = 1;
      }
    }
  }, 1);
}

// Merge equal features: bucket the keys by their first vertex (a stable counting sort, so the
// order is fixed), then sort each small bucket and count runs; each run becomes one stencil after
// the unique ones. vertex_feature_begin_ has nv + 2 entries: counting at a + 2 and filling
// through a + 1 leaves entry a at bucket a's start.
void ContactActiveSet::merge_features() {
  const int64_t nv = model_.num_vertices;
  const int64_t num_unique = num_stencils();
  std::vector<int64_t>& bucket = vertex_feature_begin_;
  bucket.assign(nv + 2, 0);
  for (const FeatureKey& f : features_) ++bucket[f.a + 2];
  for (int64_t v = 0; v < nv; ++v) bucket[v + 2] += bucket[v + 1];
  features_by_vertex_.resize(features_.size());
  for (const FeatureKey& f : features_) features_by_vertex_[bucket[f.a + 1]++] = f;

  auto before = [](const FeatureKey& l, const FeatureKey& r) { return l.b != r.b ? l.b < r.b : l.c < r.c; };
  auto same = [](const FeatureKey& l, const FeatureKey& r) { return l.b == r.b && l.c == r.c; };
  vertex_stencil_begin_.assign(nv + 1, 0);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      FeatureKey* first = features_by_vertex_.data() + bucket[v];
      FeatureKey* last = features_by_vertex_.data() + bucket[v + 1];
      std::sort(first, last, before);
      int64_t runs = 0;
      for (FeatureKey* f = first; f != last; ++f) runs += (f == first || !same(f[-1], *f));
      vertex_stencil_begin_[v + 1] = runs;
    }
  }, 1024);
  vertex_stencil_begin_[0] = num_unique;
  for (int64_t v = 0; v < nv; ++v) vertex_stencil_begin_[v + 1] += vertex_stencil_begin_[v];
  const int64_t num_stencils = vertex_stencil_begin_[nv];
  kind_.resize(num_stencils);
  vertices_.resize(4 * num_stencils);
  multiplicity_.resize(num_stencils);
  edge_edge_case_.resize(num_stencils);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      int64_t out = vertex_stencil_begin_[v] - 1;
      for (int64_t k = bucket[v]; k < bucket[v + 1]; ++k) {
        const FeatureKey& f = features_by_vertex_[k];
        if (k > bucket[v] && same(features_by_vertex_[k - 1], f)) {
          ++multiplicity_[out];
          continue;
        }
        ++out;
        kind_[out] = f.c < 0 ? ContactStencilKind::point_point : ContactStencilKind::point_edge;
        edge_edge_case_[out] = 0;
        int32_t* s = &vertices_[4 * out];
        s[0] = f.a; s[1] = f.b; s[2] = f.c; s[3] = -1;
        multiplicity_[out] = 1;
      }
    }
  }, 1024);
}

// Stencils as the Newton system sees them (held vertices dropped) and their slab sizes.
void ContactActiveSet::finish_stencils() {
  const int64_t num_stencils = this->num_stencils();
  stencils_.resize(4 * num_stencils);
  slab_begin_.resize(num_stencils + 1);
  slab_begin_[0] = 0;
  parallel_for(num_stencils, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const int n = contact_stencil_size(kind_[k]);
      for (int i = 0; i < 4; ++i) {
        const int32_t v = vertices_[4 * k + i];
        stencils_[4 * k + i] = (i < n && !model_.eliminated(v)) ? v : -1;
      }
      slab_begin_[k + 1] = 9 * n * n;
    }
  }, 4096);
  for (int64_t k = 0; k < num_stencils; ++k) slab_begin_[k + 1] += slab_begin_[k];
}

}  // namespace nexdyn
