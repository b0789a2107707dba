#include "estimation/transport.h"

#include "common/error.h"
#include "common/parallel.h"

namespace lp {

std::vector<double> TransportMatrix::Multiply(const std::vector<double>& lambda) const {
  LP_CHECK(lambda.size() == 3 * static_cast<std::size_t>(cells), "lambda size " << lambda.size());
  std::vector<double> out(3 * rows(), 0.0);
  ParallelForChunks(0, rows(), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      double s[3] = {0, 0, 0};
      for (std::int64_t k = row_start[r]; k < row_start[r + 1]; ++k)
        for (int c = 0; c < 3; ++c) s[c] += static_cast<double>(val[k][c]) * lambda[3 * col[k] + c];
      for (int c = 0; c < 3; ++c) out[3 * r + c] = s[c];
    }
  });
  return out;
}

std::vector<int> TransportMatrix::ColumnCounts() const {
  std::vector<int> counts(cells, 0);
  for (int j : col) ++counts[j];
  return counts;
}

TransportMatrix Combine(const TransportMatrix& a, const TransportMatrix& b) {
  LP_CHECK(a.rows() == b.rows() && a.cells == b.cells, "combining different problems");
  const double n = a.samples + b.samples;
  LP_CHECK(n > 0, "no samples");
  const float wa = static_cast<float>(a.samples / n), wb = static_cast<float>(b.samples / n);
  TransportMatrix out;
  out.cells = a.cells;
  out.row_view = a.row_view;
  out.row_pixel = a.row_pixel;
  out.samples = n;
  out.row_start.reserve(a.rows() + 1);
  out.row_start.push_back(0);
  out.col.reserve(a.nonzeros() + b.nonzeros());
  out.val.reserve(a.nonzeros() + b.nonzeros());
  for (std::size_t r = 0; r < a.rows(); ++r) {
    std::int64_t i = a.row_start[r], ie = a.row_start[r + 1];
    std::int64_t k = b.row_start[r], ke = b.row_start[r + 1];
    while (i < ie || k < ke) {
      if (k >= ke || (i < ie && a.col[i] < b.col[k])) {
        out.col.push_back(a.col[i]);
        out.val.push_back({wa * a.val[i][0], wa * a.val[i][1], wa * a.val[i][2]});
        ++i;
      } else if (i >= ie || b.col[k] < a.col[i]) {
        out.col.push_back(b.col[k]);
        out.val.push_back({wb * b.val[k][0], wb * b.val[k][1], wb * b.val[k][2]});
        ++k;
      } else {
        out.col.push_back(a.col[i]);
        out.val.push_back({wa * a.val[i][0] + wb * b.val[k][0], wa * a.val[i][1] + wb * b.val[k][1],
                           wa * a.val[i][2] + wb * b.val[k][2]});
        ++i;
        ++k;
      }
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.col.size()));
  }
  return out;
}

TransportMatrix AppendColumns(const TransportMatrix& A, const std::vector<std::vector<float>>& columns) {
  for (const auto& c : columns) LP_CHECK(c.size() == 3 * A.rows(), "column size " << c.size());
  TransportMatrix out;
  out.cells = A.cells + static_cast<int>(columns.size());
  out.row_view = A.row_view;
  out.row_pixel = A.row_pixel;
  out.samples = A.samples;
  out.row_start.reserve(A.rows() + 1);
  out.row_start.push_back(0);
  for (std::size_t r = 0; r < A.rows(); ++r) {
    for (std::int64_t k = A.row_start[r]; k < A.row_start[r + 1]; ++k) {
      out.col.push_back(A.col[k]);
      out.val.push_back(A.val[k]);
    }
    for (std::size_t j = 0; j < columns.size(); ++j) {
      const float* v = &columns[j][3 * r];
      if (v[0] != 0 || v[1] != 0 || v[2] != 0) {
        out.col.push_back(A.cells + static_cast<int>(j));
        out.val.push_back({v[0], v[1], v[2]});
      }
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.col.size()));
  }
  return out;
}

TransportMatrix SelectRows(const TransportMatrix& A, const std::vector<std::uint8_t>& keep, bool want) {
  LP_CHECK(keep.size() == A.rows(), "row mask size");
  TransportMatrix out;
  out.cells = A.cells;
  out.samples = A.samples;
  out.row_start.push_back(0);
  for (std::size_t r = 0; r < A.rows(); ++r) {
    if ((keep[r] != 0) != want) continue;
    out.row_view.push_back(A.row_view[r]);
    out.row_pixel.push_back(A.row_pixel[r]);
    for (std::int64_t k = A.row_start[r]; k < A.row_start[r + 1]; ++k) {
      out.col.push_back(A.col[k]);
      out.val.push_back(A.val[k]);
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.col.size()));
  }
  return out;
}

}  // namespace lp
