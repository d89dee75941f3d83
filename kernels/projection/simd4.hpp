// Four doubles handled as one value: the lane type that lets the range drivers run the element
// kernels on four tets per instruction (one AVX2 ymm register per value).
//
// Kernels are templates on a lane type T and are instantiated twice: T = double for the element
// layer (one tet, the version the finite-difference tests check) and T = Double4 in the range
// drivers (four tets). Both spell the same: arithmetic operators (GCC/Clang vector extensions act
// lane-wise and broadcast scalar operands), comparisons (a bool, or a lane mask with all bits set
// where true) and the simd:: functions below. A data-dependent branch becomes select(); a rare
// fallback tests any(mask) and then repairs the affected lanes one at a time.
//
// Lanes never interact, so a tet's result does not depend on which other tets share its pack:
// range drivers give the same bits whatever the chunking.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace nexdyn {

using Double4 = double __attribute__((vector_size(32)));
// What comparing two Double4 gives: 64-bit integer lanes, all ones where true.
using Mask4 = decltype(Double4{} < Double4{});

namespace simd {

template <typename T>
struct LaneTraits;
template <>
struct LaneTraits<double> {
  using Mask = bool;
  static constexpr int kWidth = 1;
};
template <>
struct LaneTraits<Double4> {
  using Mask = Mask4;
  static constexpr int kWidth = 4;
};
template <typename T>
using MaskOf = typename LaneTraits<T>::Mask;

// The value v in every lane.
template <typename T>
inline T splat(double v);
template <>
inline double splat<double>(double v) {
  return v;
}
template <>
inline Double4 splat<Double4>(double v) {
  return Double4{v, v, v, v};
}

inline double select(bool m, double a, double b) { return m ? a : b; }
inline Double4 select(Mask4 m, Double4 a, Double4 b) { return m ? a : b; }

inline bool any(bool m) { return m; }
inline bool all(bool m) { return m; }
#if defined(__AVX__)
inline bool any(Mask4 m) { return _mm256_movemask_pd(__m256d(m)) != 0; }
inline bool all(Mask4 m) { return _mm256_movemask_pd(__m256d(m)) == 0xF; }
#else
inline bool any(Mask4 m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }
inline bool all(Mask4 m) { return (m[0] & m[1] & m[2] & m[3]) != 0; }
#endif

// Finite (not inf, not NaN) lanes: x - x is 0 exactly for finite x and NaN otherwise.
inline bool is_finite(double x) { return x - x == 0.0; }
inline Mask4 is_finite(Double4 x) { return x - x == 0.0; }

inline double sqrt(double x) { return std::sqrt(x); }
inline double abs(double x) { return std::abs(x); }
inline double max(double a, double b) { return a > b ? a : b; }
inline double min(double a, double b) { return a < b ? a : b; }

#if defined(__AVX__)
inline Double4 sqrt(Double4 x) { return Double4(_mm256_sqrt_pd(__m256d(x))); }
#else
inline Double4 sqrt(Double4 x) {
  return Double4{std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3])};
}
#endif
inline Double4 abs(Double4 x) { return select(x < 0.0, -x, x); }
inline Double4 max(Double4 a, Double4 b) { return select(a > b, a, b); }
inline Double4 min(Double4 a, Double4 b) { return select(a < b, a, b); }

// Natural logarithm of positive, finite, normal x (no checks), within 2 ulp; the same code for
// both lane types (libm has no 4-wide log we can call, and one implementation keeps the two
// instantiations of a kernel in agreement). Method:
//   x = 2^k m with m in [sqrt(1/2), sqrt(2)), read off the bits: subtracting the bits of
//   sqrt(1/2) from those of x leaves k in the exponent field (a bias of 1023 keeps it positive,
//   so a logical shift suffices: AVX2 has no 64-bit arithmetic shift), and k is removed from the
//   exponent of x to give m;
//   log m = 2 atanh(s) with s = f / (2 + f), f = m - 1 (exact), |s| < 0.172: written as
//   f - s (f - R(s^2)), R(z) = sum_{i=1..10} 2 z^i / (2 i + 1), truncation < 1e-18 relative;
//   log x = k ln2_hi + (log m + k ln2_lo), ln2 split so that k ln2_hi is exact.
template <typename T>
inline T log(T x) {
  using Bits = std::conditional_t<std::is_same_v<T, double>, uint64_t,
                                  uint64_t __attribute__((vector_size(32)))>;
  constexpr uint64_t kSqrtHalfBits = 0x3FE6A09E667F3BCDull;  // bits of sqrt(1/2)
  constexpr uint64_t kOneExponent = 1023ull << 52;
  Bits bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const Bits k_biased = (bits - kSqrtHalfBits + kOneExponent) >> 52;  // k + 1023
  const Bits m_bits = bits - (k_biased << 52) + kOneExponent;
  // k as a double, exactly: put k + 1023 in the mantissa of 2^52 and subtract 2^52 + 1023.
  const Bits k_magic = k_biased | 0x4330000000000000ull;
  T m, k;
  std::memcpy(&m, &m_bits, sizeof(m));
  std::memcpy(&k, &k_magic, sizeof(k));
  k = k - (4503599627370496.0 + 1023.0);

  const T f = m - 1.0;
  const T s = f / (2.0 + f);
  const T z = s * s;
  T R = z * (2.0 / 21.0) + 2.0 / 19.0;
  R = R * z + 2.0 / 17.0;
  R = R * z + 2.0 / 15.0;
  R = R * z + 2.0 / 13.0;
  R = R * z + 2.0 / 11.0;
  R = R * z + 2.0 / 9.0;
  R = R * z + 2.0 / 7.0;
  R = R * z + 2.0 / 5.0;
  R = R * z + 2.0 / 3.0;
  R = R * z;
  const T log_m = f - s * (f - R);
  constexpr double kLn2Hi = 6.93147180369123816490e-01;  // 32 significant bits: k ln2_hi exact
  constexpr double kLn2Lo = 1.90821492927058770002e-10;  // ln 2 - kLn2Hi
  return k * kLn2Hi + (log_m + k * kLn2Lo);
}

// Lane access, identical for both lane types (l is ignored for double).
inline double get_lane(double x, int) { return x; }
inline double get_lane(const Double4& x, int l) { return x[l]; }
inline void set_lane(double& x, int, double v) { x = v; }
inline void set_lane(Double4& x, int l, double v) { x[l] = v; }
inline bool get_lane(bool m, int) { return m; }
inline bool get_lane(const Mask4& m, int l) { return m[l] != 0; }

// Unaligned load / store of four consecutive doubles.
inline Double4 load4(const double* p) {
  Double4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void store4(double* p, Double4 v) { std::memcpy(p, &v, sizeof(v)); }

// Non-temporal ("streaming") store of four doubles to 16-byte aligned p: the data go to memory
// through write-combining buffers without first reading the target line into the cache (no
// read-for-ownership) and without evicting useful lines. Right for large output slabs that are
// read back only later. Call stream_fence() after the last one, before other threads read.
inline void stream4(double* p, Double4 v) {
#if defined(__AVX__)
  if ((reinterpret_cast<uintptr_t>(p) & 31) == 0) {
    _mm256_stream_pd(p, __m256d(v));
  } else {
    const __m256d w = __m256d(v);
    _mm_stream_pd(p, _mm256_castpd256_pd128(w));
    _mm_stream_pd(p + 2, _mm256_extractf128_pd(w, 1));
  }
#else
  store4(p, v);
#endif
}
inline void stream_fence() {
#if defined(__AVX__)
  _mm_sfence();
#endif
}

// In-register 4x4 transpose: afterwards lane l of a, b, c, d holds what was lane 0, 1, 2, 3 of
// the l-th input. Converts between one-value-per-tet-lane (kernel) and one-tet-per-row (memory).
inline void transpose4(Double4& a, Double4& b, Double4& c, Double4& d) {
#if defined(__clang__)
  const Double4 t0 = __builtin_shufflevector(a, b, 0, 4, 2, 6);
  const Double4 t1 = __builtin_shufflevector(a, b, 1, 5, 3, 7);
  const Double4 t2 = __builtin_shufflevector(c, d, 0, 4, 2, 6);
  const Double4 t3 = __builtin_shufflevector(c, d, 1, 5, 3, 7);
  a = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
  b = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
  c = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
  d = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
#else
  const Double4 t0 = __builtin_shuffle(a, b, Mask4{0, 4, 2, 6});
  const Double4 t1 = __builtin_shuffle(a, b, Mask4{1, 5, 3, 7});
  const Double4 t2 = __builtin_shuffle(c, d, Mask4{0, 4, 2, 6});
  const Double4 t3 = __builtin_shuffle(c, d, Mask4{1, 5, 3, 7});
  a = __builtin_shuffle(t0, t2, Mask4{0, 1, 4, 5});
  b = __builtin_shuffle(t1, t3, Mask4{0, 1, 4, 5});
  c = __builtin_shuffle(t0, t2, Mask4{2, 3, 6, 7});
  d = __builtin_shuffle(t1, t3, Mask4{2, 3, 6, 7});
#endif
}

}  // namespace simd
}  // namespace nexdyn
