// Issue 20 experiment (docs/performance.md): a hash of the double CCD's verdicts and tois over
// 200,000 random queries, to compare two versions of kernels/ccd bit for bit. Not part of the
// build. From the repository root, the current version and the one before issue 20:
//   g++ -O3 -march=native -std=c++20 -I. -I/usr/include/eigen3 docs/experiments/issue20_ccd_bits.cpp \
//       kernels/ccd/ccd.cpp -o /tmp/ccd_new && /tmp/ccd_new
//   mkdir -p /tmp/ccd_old/kernels/ccd && for f in ccd.cpp ccd.hpp ccd_distance.hpp; do
//     git show 24b1d62:kernels/ccd/$f > /tmp/ccd_old/kernels/ccd/$f; done
//   g++ -O3 -march=native -std=c++20 -I/tmp/ccd_old -I/usr/include/eigen3 docs/experiments/issue20_ccd_bits.cpp \
//       /tmp/ccd_old/kernels/ccd/ccd.cpp -o /tmp/ccd_old/run && /tmp/ccd_old/run
#include "kernels/ccd/ccd.hpp"
#include <cstdio>
#include <random>
#include <cstring>
using namespace nexdyn;
int main() {
  std::mt19937 rng(5); std::uniform_real_distribution<double> u(-1, 1);
  unsigned long long h = 1469598103934665603ull; int hits = 0;
  for (int t = 0; t < 200000; ++t) {
    Eigen::Vector3d x[8]; for (auto& v : x) v = Eigen::Vector3d(u(rng), u(rng), u(rng));
    double toi = -1, toi2 = -1;
    bool a = point_triangle_ccd(x[0],x[1],x[2],x[3],x[4],x[5],x[6],x[7], 1e-3 * (t % 7), 1.0, toi);
    bool b = edge_edge_ccd(x[0],x[1],x[2],x[3],x[4],x[5],x[6],x[7], 1e-3 * (t % 5), 1.0, toi2);
    hits += a + b;
    unsigned long long bits[2]; std::memcpy(bits, &toi, 8); std::memcpy(bits + 1, &toi2, 8);
    for (auto q : bits) { h ^= q + (a << 1) + b; h *= 1099511628211ull; }
  }
  printf("hash %llx hits %d\n", h, hits);
}
