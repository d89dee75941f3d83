// Range drivers of tetrahedral elasticity (see elasticity_range.hpp).
//
// Tets are processed four at a time: the element kernels (tet_kernels.hpp) are instantiated with
// the lane type Double4, so each AVX2 instruction works on the same quantity of four tets. That
// turns the long dependency chains of a tet (SVD, log, divisions) into four independent ones and
// does 4x the arithmetic per instruction. Around the kernel, the data are transposed between
// memory (one tet after the other: AoS) and lanes (one quantity of four tets: SoA):
//   in:  each corner is one masked 4-wide load per tet (random vertex ids) and a 4x4 transpose;
//        Dm^-1 of four consecutive tets is two 4x4 transposes and a gather; volumes one load.
//   out: per-tet slabs are written by 4x4 transposes of groups of four consecutive outputs; the
//        Hessian slab with streaming stores (see hessian_range).
// The last, partial pack repeats its last tet in the spare lanes and stores only the real ones, so
// a tet's result never depends on where a chunk starts or ends (lanes are independent).
#include "kernels/elasticity/elasticity_range.hpp"

#include "kernels/elasticity/energy_density.hpp"
#include "kernels/elasticity/tet_kernels.hpp"
#include "kernels/projection/simd4.hpp"

#include <algorithm>
#include <cstdint>
#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace nexdyn {

namespace {

constexpr int kPack = 4;

// Tets first .. first + count - 1 into the lanes (count in 1..4); spare lanes repeat the last tet.
TetLanes<Double4> load_pack(const TetRange& r, int64_t first, int count) {
  int64_t tet[kPack];
  for (int l = 0; l < kPack; ++l) tet[l] = first + std::min(l, count - 1);
  TetLanes<Double4> p;
  for (int k = 0; k < 4; ++k) {
    // Corner k of the four tets: one 4-wide load per tet (x, y, z and a fourth lane that is masked
    // off, so reading past the last vertex cannot fault), then a transpose to x, y, z lanes.
    Double4 c[kPack];
    for (int l = 0; l < kPack; ++l) {
      const double* xk = r.x + 3 * int64_t(r.tets[4 * tet[l] + k]);
#if defined(__AVX__)
      c[l] = Double4(_mm256_maskload_pd(xk, __m256i(Mask4{-1, -1, -1, 0})));
#else
      c[l] = Double4{xk[0], xk[1], xk[2], 0.0};
#endif
    }
    simd::transpose4(c[0], c[1], c[2], c[3]);
    p.x[k] = {{c[0], c[1], c[2]}};
  }
  if (count == kPack) {
    // Dm^-1 of four consecutive tets: 36 consecutive doubles, entries 0-3 and 4-7 of each tet
    // transposed into lanes, entry 8 gathered.
    const double* d = r.Dm_inv + 9 * first;
    Double4 a0 = simd::load4(d), a1 = simd::load4(d + 9), a2 = simd::load4(d + 18),
            a3 = simd::load4(d + 27);
    simd::transpose4(a0, a1, a2, a3);
    Double4 b0 = simd::load4(d + 4), b1 = simd::load4(d + 13), b2 = simd::load4(d + 22),
            b3 = simd::load4(d + 31);
    simd::transpose4(b0, b1, b2, b3);
    const Double4 e8{d[8], d[17], d[26], d[35]};
    const Double4 entries[9] = {a0, a1, a2, a3, b0, b1, b2, b3, e8};
    for (int i = 0; i < 9; ++i) p.Dm_inv(i % 3, i / 3) = entries[i];
    p.volume = simd::load4(r.volume + first);
  } else {
    for (int l = 0; l < kPack; ++l) {
      const double* d = r.Dm_inv + 9 * tet[l];
      for (int i = 0; i < 9; ++i) p.Dm_inv(i % 3, i / 3)[l] = d[i];
      p.volume[l] = r.volume[tet[l]];
    }
  }
  return p;
}

// Writes N values per tet (N a multiple of 4; lane l of values[i] is entry i of tet first + l) to
// out + N * tet, for the first `count` tets of the pack.
template <int N>
inline void store_pack(const Double4 values[N], int count, double* out, int64_t first) {
  static_assert(N % 4 == 0);
  double* base = out + int64_t(N) * first;
  if (count == kPack) {
    for (int i = 0; i < N; i += 4) {
      Double4 a = values[i], b = values[i + 1], c = values[i + 2], d = values[i + 3];
      simd::transpose4(a, b, c, d);  // now a = entries i..i+3 of tet 0, b of tet 1, ...
      simd::store4(base + i, a);
      simd::store4(base + N + i, b);
      simd::store4(base + 2 * N + i, c);
      simd::store4(base + 3 * N + i, d);
    }
  } else {
    for (int l = 0; l < count; ++l)
      for (int i = 0; i < N; ++i) base[int64_t(N) * l + i] = values[i][l];
  }
}

// The same with streaming stores (out 16-byte aligned). The pack is transposed into an L1
// staging buffer first, so that each tet's slab is then streamed front to back: a cache line
// shared by two consecutive slabs (a buffer that is not 64-byte aligned) is completed while its
// write-combining buffer is still open, instead of being flushed half full.
template <int N>
inline void stream_pack(const Double4 values[N], int count, double* out, int64_t first) {
  alignas(32) double staging[kPack][N];
  store_pack<N>(values, kPack, &staging[0][0], 0);
  double* base = out + int64_t(N) * first;
  for (int l = 0; l < count; ++l)
    for (int i = 0; i < N; i += 4)
      simd::stream4(base + int64_t(N) * l + i, simd::load4(&staging[l][i]));
}

}  // namespace

template <MaterialModel M>
double energy_range(const TetRange& r, int64_t begin, int64_t end, const LameParameters& lame) {
  double total = 0.0;
  for (int64_t t = begin; t < end; t += kPack) {
    const int count = int(std::min<int64_t>(kPack, end - t));
    const Double4 e = tet_energy_kernel<M>(load_pack(r, t, count), lame);
    for (int l = 0; l < count; ++l) total += e[l];  // tet order, as a scalar loop would
  }
  return total;
}

template <MaterialModel M>
int64_t gradient_range(const TetRange& r, int64_t begin, int64_t end, const LameParameters& lame,
                       double* energy, double* gradient) {
  int64_t inverted = 0;
  for (int64_t t = begin; t < end; t += kPack) {
    const int count = int(std::min<int64_t>(kPack, end - t));
    Double4 g[12];
    const Double4 e = tet_gradient_kernel<M>(load_pack(r, t, count), lame, g);
    store_pack<12>(g, count, gradient, t);
    for (int l = 0; l < count; ++l) {
      energy[t + l] = e[l];
      if constexpr (M == MaterialModel::neohookean) inverted += (e[l] == kInfinity);
    }
  }
  return inverted;
}

// The Hessian slab is 1152 B per tet, written once and gathered later by another pass: with
// ordinary stores every line is first read from memory (read-for-ownership) and the stores back up
// behind those misses, which halved the throughput. Streaming stores skip the read; they need
// 16-byte alignment, which std::vector<double> provides (32 or 64 is better still).
template <MaterialModel M>
int64_t hessian_range(const TetRange& r, int64_t begin, int64_t end, const LameParameters& lame,
                      double* gradient, double* hessian) {
  const bool stream = (reinterpret_cast<uintptr_t>(hessian) & 15) == 0;
  int64_t inverted = 0;
  for (int64_t t = begin; t < end; t += kPack) {
    const int count = int(std::min<int64_t>(kPack, end - t));
    Double4 g[12], H[144];
    const Double4 e = tet_hessian_kernel<M>(load_pack(r, t, count), lame, g, H);
    store_pack<12>(g, count, gradient, t);
    if (stream) {
      stream_pack<144>(H, count, hessian, t);
    } else {
      store_pack<144>(H, count, hessian, t);
    }
    if constexpr (M == MaterialModel::neohookean)
      for (int l = 0; l < count; ++l) inverted += (e[l] == kInfinity);
  }
  if (stream) simd::stream_fence();  // streamed data visible before the caller moves on
  return inverted;
}

template double energy_range<MaterialModel::linear>(const TetRange&, int64_t, int64_t,
                                                    const LameParameters&);
template double energy_range<MaterialModel::stvk>(const TetRange&, int64_t, int64_t,
                                                  const LameParameters&);
template double energy_range<MaterialModel::corotated>(const TetRange&, int64_t, int64_t,
                                                       const LameParameters&);
template double energy_range<MaterialModel::neohookean>(const TetRange&, int64_t, int64_t,
                                                        const LameParameters&);
template int64_t gradient_range<MaterialModel::linear>(const TetRange&, int64_t, int64_t,
                                                       const LameParameters&, double*, double*);
template int64_t gradient_range<MaterialModel::stvk>(const TetRange&, int64_t, int64_t,
                                                     const LameParameters&, double*, double*);
template int64_t gradient_range<MaterialModel::corotated>(const TetRange&, int64_t, int64_t,
                                                          const LameParameters&, double*, double*);
template int64_t gradient_range<MaterialModel::neohookean>(const TetRange&, int64_t, int64_t,
                                                           const LameParameters&, double*,
                                                           double*);
template int64_t hessian_range<MaterialModel::linear>(const TetRange&, int64_t, int64_t,
                                                      const LameParameters&, double*, double*);
template int64_t hessian_range<MaterialModel::stvk>(const TetRange&, int64_t, int64_t,
                                                    const LameParameters&, double*, double*);
template int64_t hessian_range<MaterialModel::corotated>(const TetRange&, int64_t, int64_t,
                                                         const LameParameters&, double*, double*);
template int64_t hessian_range<MaterialModel::neohookean>(const TetRange&, int64_t, int64_t,
                                                          const LameParameters&, double*, double*);

double energy_range(MaterialModel model, const TetRange& r, int64_t begin, int64_t end,
                    const LameParameters& lame) {
  return with_material_model(model,
                             [&](auto m) { return energy_range<m()>(r, begin, end, lame); });
}

int64_t gradient_range(MaterialModel model, const TetRange& r, int64_t begin, int64_t end,
                       const LameParameters& lame, double* energy, double* gradient) {
  return with_material_model(model, [&](auto m) {
    return gradient_range<m()>(r, begin, end, lame, energy, gradient);
  });
}

int64_t hessian_range(MaterialModel model, const TetRange& r, int64_t begin, int64_t end,
                      const LameParameters& lame, double* gradient, double* hessian) {
  return with_material_model(model, [&](auto m) {
    return hessian_range<m()>(r, begin, end, lame, gradient, hessian);
  });
}

}  // namespace nexdyn
