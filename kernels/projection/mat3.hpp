// 3-vectors and 3x3 matrices of lanes (T = double or Double4, see simd4.hpp), with just the
// operations the per-tet kernels need. Eigen's fixed-size types cannot hold a vector-extension
// scalar, and for T = double plain scalar code on 3x3 is as fast as Eigen's partial packets.
// Column-major like Eigen: M(r, c) is col[c][r]. to_mat3 / to_eigen convert at the API boundary.
#pragma once

#include "kernels/projection/simd4.hpp"

#include <Eigen/Core>

namespace nexdyn {

template <typename T>
struct Vec3 {
  T v[3];
  T& operator[](int i) { return v[i]; }
  const T& operator[](int i) const { return v[i]; }
};

template <typename T>
struct Mat3 {
  Vec3<T> col[3];
  T& operator()(int r, int c) { return col[c][r]; }
  const T& operator()(int r, int c) const { return col[c][r]; }
};

template <typename T>
inline Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {{a[0] + b[0], a[1] + b[1], a[2] + b[2]}};
}
template <typename T>
inline Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {{a[0] - b[0], a[1] - b[1], a[2] - b[2]}};
}
template <typename T>
inline Vec3<T> operator-(const Vec3<T>& a) {
  return {{-a[0], -a[1], -a[2]}};
}
// S is T or double (a double is broadcast to every lane).
template <typename T, typename S>
inline Vec3<T> operator*(const Vec3<T>& a, const S& s) {
  return {{a[0] * s, a[1] * s, a[2] * s}};
}
template <typename T>
inline T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
template <typename T>
inline T squared_norm(const Vec3<T>& a) {
  return dot(a, a);
}
template <typename T>
inline Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}};
}
template <typename T>
inline Vec3<T> select(simd::MaskOf<T> m, const Vec3<T>& a, const Vec3<T>& b) {
  return {{simd::select(m, a[0], b[0]), simd::select(m, a[1], b[1]),
           simd::select(m, a[2], b[2])}};
}

template <typename T>
inline Mat3<T> identity3() {
  const T one = simd::splat<T>(1.0), zero = simd::splat<T>(0.0);
  return {{{{one, zero, zero}}, {{zero, one, zero}}, {{zero, zero, one}}}};
}
template <typename T>
inline Mat3<T> operator+(const Mat3<T>& A, const Mat3<T>& B) {
  return {{A.col[0] + B.col[0], A.col[1] + B.col[1], A.col[2] + B.col[2]}};
}
template <typename T>
inline Mat3<T> operator-(const Mat3<T>& A, const Mat3<T>& B) {
  return {{A.col[0] - B.col[0], A.col[1] - B.col[1], A.col[2] - B.col[2]}};
}
template <typename T, typename S>
inline Mat3<T> operator*(const Mat3<T>& A, const S& s) {
  return {{A.col[0] * s, A.col[1] * s, A.col[2] * s}};
}
template <typename T>
inline Vec3<T> operator*(const Mat3<T>& A, const Vec3<T>& x) {
  return A.col[0] * x[0] + A.col[1] * x[1] + A.col[2] * x[2];
}
template <typename T>
inline Mat3<T> operator*(const Mat3<T>& A, const Mat3<T>& B) {
  return {{A * B.col[0], A * B.col[1], A * B.col[2]}};
}
template <typename T>
inline Mat3<T> transpose(const Mat3<T>& A) {
  Mat3<T> R;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) R(r, c) = A(c, r);
  return R;
}
// A^T B: entries are dot products of columns.
template <typename T>
inline Mat3<T> transpose_times(const Mat3<T>& A, const Mat3<T>& B) {
  Mat3<T> R;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) R(r, c) = dot(A.col[r], B.col[c]);
  return R;
}
// A B^T = sum_k a_k b_k^T over the columns.
template <typename T>
inline Mat3<T> times_transpose(const Mat3<T>& A, const Mat3<T>& B) {
  Mat3<T> R;
  for (int c = 0; c < 3; ++c)
    R.col[c] = A.col[0] * B(c, 0) + A.col[1] * B(c, 1) + A.col[2] * B(c, 2);
  return R;
}
template <typename T>
inline T trace(const Mat3<T>& A) {
  return A(0, 0) + A(1, 1) + A(2, 2);
}
template <typename T>
inline T squared_norm(const Mat3<T>& A) {
  return squared_norm(A.col[0]) + squared_norm(A.col[1]) + squared_norm(A.col[2]);
}
// Cofactor matrix cof(A) = det(A) A^-T: its columns are cross products of the columns of A.
template <typename T>
inline Mat3<T> cofactor(const Mat3<T>& A) {
  return {{cross(A.col[1], A.col[2]), cross(A.col[2], A.col[0]), cross(A.col[0], A.col[1])}};
}
template <typename T>
inline Mat3<T> select(simd::MaskOf<T> m, const Mat3<T>& A, const Mat3<T>& B) {
  return {{select(m, A.col[0], B.col[0]), select(m, A.col[1], B.col[1]),
           select(m, A.col[2], B.col[2])}};
}

inline Mat3<double> to_mat3(const Eigen::Matrix3d& A) {
  Mat3<double> R;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) R(r, c) = A(r, c);
  return R;
}
inline Eigen::Matrix3d to_eigen(const Mat3<double>& A) {
  Eigen::Matrix3d R;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) R(r, c) = A(r, c);
  return R;
}
inline Vec3<double> to_vec3(const Eigen::Vector3d& a) { return {{a[0], a[1], a[2]}}; }
inline Eigen::Vector3d to_eigen(const Vec3<double>& a) { return {a[0], a[1], a[2]}; }

}  // namespace nexdyn
