// Global assembly against independent references: the sparse pattern against a dense sum of the
// element Hessians, the global gradient against finite differences of the global energy,
// bitwise equality of everything for 1 and 2 threads and for any size of the Hessian blocks.
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstring>
#include <random>

using namespace nexdyn;

namespace {

Scene small_scene(const std::string& model) {
  return test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 },
    "materials": { "a": { "model": ")" + model + R"(", "youngs": 1e5, "poisson": 0.3, "density": 1000 },
                   "b": { "model": "stvk", "youngs": 3e5, "poisson": 0.2, "density": 500 } },
    "bodies": [ { "box": { "size": [1, 0.5, 0.5], "cells": [3, 2, 2] }, "material": "a" },
                { "box": { "size": [0.5, 0.5, 0.5], "cells": [1, 1, 2] }, "material": "b", "translate": [2, 0, 0] } ]
  })", "assembly_" + model);
}

}  // namespace

TEST_CASE("sparse Hessian equals the dense sum of projected element Hessians") {
  for (MaterialModel mm : kAllMaterialModels) {
    CAPTURE(material_model_name(mm));
    Scene scene = small_scene(std::string(material_model_name(mm)));
    const Model& model = scene.model;
    ElasticAssembly assembly(model);
    const std::vector<double> x = test::perturbed(model.rest_positions, 0.02, 7);
    std::vector<double> grad(model.num_dofs()), values(assembly.pattern().nnz());
    assembly.gradient_hessian(x.data(), grad.data(), values.data());

    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(model.num_dofs(), model.num_dofs());
    Eigen::VectorXd dense_grad = Eigen::VectorXd::Zero(model.num_dofs());
    for (int32_t t = 0; t < model.num_tets; ++t) {
      Eigen::Matrix<double, 3, 4> xt;
      for (int c = 0; c < 4; ++c) xt.col(c) = Eigen::Vector3d::Map(&x[3 * model.tets[4 * t + c]]);
      const Material& mat = model.materials[model.tet_material[t]];
      Eigen::Matrix<double, 12, 1> g;
      Eigen::Matrix<double, 12, 12> H;
      tet_energy_gradient_hessian(mat.model, xt, Eigen::Matrix3d::Map(&model.Dm_inv[9 * t]),
                                  model.rest_volume[t], mat.lame, g, H);
      for (int a = 0; a < 4; ++a) {
        dense_grad.segment<3>(3 * model.tets[4 * t + a]) += g.segment<3>(3 * a);
        for (int b = 0; b < 4; ++b)
          dense.block<3, 3>(3 * model.tets[4 * t + a], 3 * model.tets[4 * t + b]) += H.block<3, 3>(3 * a, 3 * b);
      }
    }
    const Eigen::MatrixXd sparse = test::dense_from(assembly.pattern(), values);
    CHECK((sparse - dense).norm() <= 1e-10 * dense.norm());
    CHECK((Eigen::VectorXd::Map(grad.data(), grad.size()) - dense_grad).norm() <= 1e-10 * dense_grad.norm());
    // Every entry of the dense matrix that is structurally non-zero is in the pattern.
    int64_t dense_nonzeros = 0;
    for (int64_t c = 0; c < dense.cols(); ++c)
      for (int64_t r = 0; r <= c; ++r) dense_nonzeros += dense(r, c) != 0.0;
    CHECK(dense_nonzeros <= assembly.pattern().nnz());
  }
}

TEST_CASE("incremental potential: gradient matches central differences of the energy") {
  Scene scene = small_scene("neohookean");
  const Model& model = scene.model;
  ElasticAssembly assembly(model);
  StepHistory history;
  IncrementalPotential potential(model, assembly, history);
  const std::vector<double> x_tilde = test::perturbed(model.rest_positions, 0.01, 3);
  potential.begin_step(x_tilde, weights_context(2 * 0.5 * 0.25 * 0.01 * 0.01, 2 * 0.5 * 0.25 * 0.01 * 0.01, true));
  std::vector<double> x = test::perturbed(model.rest_positions, 0.02, 11);
  std::vector<double> grad(model.num_dofs()), values(potential.pattern().nnz());
  potential.gradient_hessian(x.data(), grad.data(), values.data());
  const double h = 1e-6;
  double worst = 0.0, scale = 0.0;
  for (int64_t i = 0; i < model.num_dofs(); i += 5) {
    const double xi = x[i];
    x[i] = xi + h;
    const double ep = potential.energy(x.data());
    x[i] = xi - h;
    const double em = potential.energy(x.data());
    x[i] = xi;
    worst = std::max(worst, std::abs((ep - em) / (2 * h) - grad[i]));
    scale = std::max(scale, std::abs(grad[i]));
  }
  CHECK(worst <= 1e-6 * scale);
}

TEST_CASE("assembly is bitwise identical with 1 and 2 threads") {
  Scene scene = test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [12, 12, 12] }, "material": "a" } ]
  })", "threads");
  const Model& model = scene.model;
  const std::vector<double> x = test::perturbed(model.rest_positions, 0.005, 5);
  auto evaluate = [&](int threads) {
    test::ThreadsScope limit(threads);
    ElasticAssembly assembly(model);
    std::vector<double> out(model.num_dofs() + assembly.pattern().nnz() + 1);
    assembly.gradient_hessian(x.data(), out.data(), out.data() + model.num_dofs());
    out.back() = assembly.energy(x.data());
    return out;
  };
  const std::vector<double> one = evaluate(1), two = evaluate(2);
  REQUIRE(one.size() == two.size());
  CHECK(std::memcmp(one.data(), two.data(), one.size() * sizeof(double)) == 0);
}

TEST_CASE("Hessian blocks change no value: any block size, with coupling groups and a subset") {
  // Three bodies; a coupling group (as joints add) ties a vertex of the first to one of the third,
  // across blocks. Block size 1 makes every body its own block, 1e9 makes one block of all.
  Scene scene = test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 },
                   "b": { "model": "stvk", "youngs": 3e5, "poisson": 0.2, "density": 500 } },
    "bodies": [ { "box": { "size": [1, 0.5, 0.5], "cells": [3, 2, 2] }, "material": "a" },
                { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "b", "translate": [2, 0, 0] },
                { "box": { "size": [0.5, 0.5, 0.5], "cells": [1, 1, 2] }, "material": "a", "translate": [4, 0, 0] } ]
  })", "assembly_blocks");
  const Model& model = scene.model;
  REQUIRE(model.bodies.size() == 3);
  const int32_t last = model.bodies[2].vertex_begin;
  const std::vector<int32_t> groups = {0, 1, last, last + 1};
  const std::vector<double> x = test::perturbed(model.rest_positions, 0.02, 13);
  auto assemble = [&](int64_t block_tets, const ActiveSubset* subset) {
    ElasticAssembly assembly(model, groups, block_tets);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    for (int k = 0; k < 144; ++k) assembly.coupling_slabs()[k] = uniform(rng);
    std::vector<double> out(model.num_dofs() + assembly.pattern().nnz(), -7.0);
    assembly.gradient_hessian(x.data(), out.data(), out.data() + model.num_dofs(), subset);
    return out;
  };
  const std::vector<double> one_block = assemble(1'000'000'000, nullptr);
  const std::vector<double> per_body = assemble(1, nullptr);
  REQUIRE(one_block.size() == per_body.size());
  CHECK(std::memcmp(one_block.data(), per_body.data(), one_block.size() * sizeof(double)) == 0);
  CHECK(std::count(one_block.begin(), one_block.end(), -7.0) == 0);  // every entry written

  // The second body alone: its gradient entries and Hessian columns are the same numbers.
  const BodyRange& body = model.bodies[1];
  ActiveSubset subset;
  subset.vertices = {{body.vertex_begin, body.vertex_begin + body.vertex_count}};
  subset.tets = {{body.tet_begin, body.tet_begin + body.tet_count}};
  subset.vertex_mask.assign(model.num_vertices, 0);
  std::fill_n(subset.vertex_mask.begin() + body.vertex_begin, body.vertex_count, 1);
  const std::vector<double> part = assemble(1, &subset);
  const ElasticAssembly reference(model, groups);
  const int64_t n = model.num_dofs();
  int64_t compared = 0;
  for (int64_t i = 3 * body.vertex_begin; i < 3 * (body.vertex_begin + body.vertex_count); ++i) {
    CHECK(part[i] == one_block[i]);
    for (int64_t k = reference.pattern().col_ptr[i]; k < reference.pattern().col_ptr[i + 1]; ++k, ++compared)
      CHECK(part[n + k] == one_block[n + k]);
  }
  CHECK(compared > 0);
  CHECK(part[0] == -7.0);  // the first body's gradient is left alone
}
