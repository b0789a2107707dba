#pragma once
/// The light-transport matrix A (paper Eq. 12): for each traced pixel (row) and
/// environment cell (column), dI_pc / dlambda_jc per colour channel c. Sparse
/// rows (a pixel touches only the cells its samples reached), float values.
#include <array>
#include <cstdint>
#include <vector>

namespace lp {

struct TransportMatrix {
  int cells = 0;                        ///< columns (environment cells)
  std::vector<int> row_view;            ///< view index of each row
  std::vector<int> row_pixel;           ///< pixel index (y*width + x) of each row
  std::vector<std::int64_t> row_start;  ///< CSR offsets, rows()+1 entries
  std::vector<int> col;                 ///< cell of each entry, increasing within a row
  std::vector<std::array<float, 3>> val;  ///< RGB value of each entry
  double samples = 0;                   ///< samples per pixel it averages (for combining rounds)

  std::size_t rows() const { return row_view.size(); }
  std::size_t nonzeros() const { return col.size(); }

  /// out[3*row + c] = sum_j A[row, j, c] * lambda[3*j + c].
  std::vector<double> Multiply(const std::vector<double>& lambda) const;
  /// Number of entries per column (0 = no sampled path reached the cell).
  std::vector<int> ColumnCounts() const;
};

/// Sample-count-weighted mean of two estimates of A over the same rows:
/// (a.samples*a + b.samples*b) / (a.samples + b.samples).
TransportMatrix Combine(const TransportMatrix& a, const TransportMatrix& b);

/// A with dense columns appended after its cells (each 3 * rows values, row-major RGB;
/// zeros are not stored): out.cells = A.cells + columns.size().
TransportMatrix AppendColumns(const TransportMatrix& A, const std::vector<std::vector<float>>& columns);

/// The rows r of A with keep[r] == want (same columns).
TransportMatrix SelectRows(const TransportMatrix& A, const std::vector<std::uint8_t>& keep, bool want);

}  // namespace lp
