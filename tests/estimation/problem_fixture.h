#pragma once
// A small random non-negative least-squares problem with a known sparse answer.
#include <vector>

#include "common/rng.h"
#include "estimation/objective.h"

namespace lp::test {

struct RandomProblem {
  TransportMatrix A;
  std::vector<double> truth;  // 3 * cells
  std::vector<double> y;
};

inline RandomProblem MakeRandomProblem(int rows, int cells, double density, double noise, std::uint64_t seed) {
  RandomProblem p;
  Rng rng(seed);
  p.A.cells = cells;
  p.A.samples = 1;
  p.A.row_start.push_back(0);
  for (int r = 0; r < rows; ++r) {
    p.A.row_view.push_back(0);
    p.A.row_pixel.push_back(r);
    for (int j = 0; j < cells; ++j)
      if (rng.Uniform() < density || j == r % cells) {
        p.A.col.push_back(j);
        p.A.val.push_back({static_cast<float>(rng.Uniform()), static_cast<float>(rng.Uniform()),
                           static_cast<float>(rng.Uniform())});
      }
    p.A.row_start.push_back(static_cast<std::int64_t>(p.A.col.size()));
  }
  p.truth.assign(3 * cells, 0.0);
  for (int j = 0; j < cells; j += 5)
    for (int c = 0; c < 3; ++c) p.truth[3 * j + c] = 0.5 + rng.Uniform();
  p.y = p.A.Multiply(p.truth);
  for (double& v : p.y) v += noise * (rng.Uniform() - 0.5);
  return p;
}

}  // namespace lp::test
