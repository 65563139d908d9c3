#include "core/frontend/neighbour_grid.h"

#include <pcl/point_types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/common/error.h"
#include "core/common/hash.h"
#include "core/common/radix_sort.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace ism {
namespace {

// 21 bits per axis pack a cell into one 63-bit key. Cells beyond that (more than a million cells
// from the cloud's median: 10 km at 1 cm) are clamped to the first or last one. Clamping never moves two
// cells further apart, so no neighbour is lost; far-away points only share a cell and are then
// rejected by the exact distance test.
constexpr int64_t kMaxCell = (int64_t{1} << 21) - 1;
// Keys use 63 bits, so this one is never a cell.
constexpr uint64_t kEmptyKey = ~uint64_t{0};

int64_t clampCell(double c) {
  if (!(c > 0.0)) return 0;  // also NaN
  if (c >= static_cast<double>(kMaxCell)) return kMaxCell;
  return static_cast<int64_t>(c);
}

// The cell coordinates a key packs (NeighbourGrid::keyOf).
std::array<int64_t, 3> cellOfKey(uint64_t key) {
  return {static_cast<int64_t>(key >> 42), static_cast<int64_t>((key >> 21) & kMaxCell),
          static_cast<int64_t>(key & kMaxCell)};
}

// Four consecutive points of the grid's arrays from `first` on, of which those in the lanes set
// in `lanes` are candidates: a run of candidates may end inside its last four.
struct Quad {
  uint32_t first, lanes;
};

// The candidates of a search: the runs of consecutive points the visited cells cover (the cells
// of one column within the searched z range are consecutive), cut into quads.
void appendRun(uint32_t begin, uint32_t end, std::vector<Quad>& quads) {
  for (uint32_t j = begin; j < end; j += 4) quads.push_back({j, end - j >= 4 ? 0xFu : (1u << (end - j)) - 1u});
}

// Bit 4 t + l of the bitset `within` (one bit per lane of `quads`, in order) is set when lane l
// of quads[t] is a candidate whose squared distance to p is at most r2. The distance is computed
// as everywhere in the grid, (dx * dx + dy * dy) + dz * dz in float, so the set is exactly the
// one a point-by-point test finds. With SSE2 (every x86-64) a quad takes a few instructions and
// gives its four bits at once; appending the points within one at a time, each waiting on the
// count of the previous, would be a third of forEachPoint (216 candidates per point for 26 inside
// on tum_desk's normals, by perf). The arrays must be readable 3 floats past the last point.
void markWithin(const float* x, const float* y, const float* z, const std::vector<Quad>& quads, const float p[3],
                float r2, uint64_t* within) {
  const size_t n = quads.size();
#ifdef __SSE2__
  const __m128 px = _mm_set1_ps(p[0]), py = _mm_set1_ps(p[1]), pz = _mm_set1_ps(p[2]), r = _mm_set1_ps(r2);
#endif
  for (size_t word = 0; 16 * word < n; ++word) {
    uint64_t bits = 0;  // in a register: or-ing into memory waited on the previous store
    for (size_t t = 16 * word; t < std::min(n, 16 * word + 16); ++t) {
      const uint32_t j = quads[t].first;
#ifdef __SSE2__
      const __m128 dx = _mm_sub_ps(_mm_loadu_ps(x + j), px), dy = _mm_sub_ps(_mm_loadu_ps(y + j), py),
                   dz = _mm_sub_ps(_mm_loadu_ps(z + j), pz);
      const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
      const auto lanes = static_cast<uint32_t>(_mm_movemask_ps(_mm_cmple_ps(d2, r))) & quads[t].lanes;
#else
      uint32_t lanes = 0;
      for (uint32_t l = 0; l < 4; ++l) {
        const float dx = x[j + l] - p[0], dy = y[j + l] - p[1], dz = z[j + l] - p[2];
        lanes |= static_cast<uint32_t>(dx * dx + dy * dy + dz * dz <= r2) << l;
      }
      lanes &= quads[t].lanes;
#endif
      bits |= static_cast<uint64_t>(lanes) << (4 * (t % 16));
    }
    within[word] = bits;
  }
}

// The points of the set bits of `within` (markWithin over `quads`), in order, into `at`;
// returns how many.
size_t pointsOf(const uint64_t* within, const std::vector<Quad>& quads, uint32_t* at) {
  size_t found = 0;
  for (size_t word = 0; 16 * word < quads.size(); ++word) {
    for (uint64_t bits = within[word]; bits != 0; bits &= bits - 1) {
      const size_t bit = 64 * word + static_cast<size_t>(__builtin_ctzll(bits));
      at[found++] = quads[bit / 4].first + static_cast<uint32_t>(bit % 4);
    }
  }
  return found;
}

}  // namespace

// The top bits of a full mix (core/common/hash.h).
uint64_t NeighbourGrid::slotOf(uint64_t key) const { return mix64(key) >> table_shift_; }

uint64_t NeighbourGrid::keyOf(int64_t x, int64_t y, int64_t z) const {
  return (static_cast<uint64_t>(x) << 42) | (static_cast<uint64_t>(y) << 21) | static_cast<uint64_t>(z);
}

Eigen::Array3i NeighbourGrid::cellOf(const Eigen::Vector3f& p) const {
  // floor(p / cell) depends on the point and the cell size only, so a point falls in the same cell
  // (and meets its neighbours in the same order) whatever else the cloud holds: a grid over part
  // of a cloud answers exactly as one over all of it.
  const Eigen::Vector3d scaled = p.cast<double>() * inverse_cell_exact_;
  return {static_cast<int>(clampCell(std::floor(scaled.x()) - first_cell_.x())),
          static_cast<int>(clampCell(std::floor(scaled.y()) - first_cell_.y())),
          static_cast<int>(clampCell(std::floor(scaled.z()) - first_cell_.z()))};
}

void NeighbourGrid::build(std::vector<Eigen::Vector3f> points, float cell_size) {
  if (!(std::isfinite(cell_size) && cell_size > 0.0f)) {
    throw Error(ErrorCode::kInvalidInput,
                "neighbour grid cell size " + std::to_string(cell_size) + " must be positive and finite");
  }
  if (points.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max())) {
    throw Error(ErrorCode::kInvalidInput, "neighbour grid: " + std::to_string(points.size()) + " points are too many");
  }
  cell_size_ = cell_size;
  inverse_cell_ = 1.0f / cell_size;
  // The grid is centred on the median point, so the cells around the bulk of the cloud are
  // always distinct: with an origin at the minimum, one stray point (a smoothing fit gone wild, a
  // bogus point in a user's cloud) would push every real point past the 21-bit range into a few
  // clamped cells, and the searches would become quadratic. Only points more than 2^20 cells from
  // the median share clamped cells.
  inverse_cell_exact_ = 1.0 / static_cast<double>(cell_size);
  first_cell_ = Eigen::Vector3d::Zero();
  std::vector<float> axis;
  axis.reserve(points.size());
  for (int a = 0; a < 3; ++a) {
    axis.clear();
    for (const auto& p : points) {
      if (std::isfinite(p[a])) axis.push_back(p[a]);
    }
    if (axis.empty()) continue;
    auto middle = axis.begin() + static_cast<std::ptrdiff_t>(axis.size() / 2);
    std::nth_element(axis.begin(), middle, axis.end());
    first_cell_[a] = std::floor(static_cast<double>(*middle) * inverse_cell_exact_) - static_cast<double>(kMaxCell / 2 + 1);
  }

  std::vector<std::pair<uint64_t, int>> keyed(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Array3i c = cellOf(points[i]);
    keyed[i] = {keyOf(c.x(), c.y(), c.z()), static_cast<int>(i)};
  }
  sortByKey(keyed);
  // Three more, so that a search may read its last candidates in quads (markWithin).
  x_.assign(points.size() + 3, 0.0f);
  y_.assign(points.size() + 3, 0.0f);
  z_.assign(points.size() + 3, 0.0f);
  original_index_.resize(points.size());
  cells_.clear();
  for (size_t i = 0; i < keyed.size(); ++i) {
    const Eigen::Vector3f& p = points[static_cast<size_t>(keyed[i].second)];
    x_[i] = p.x();
    y_[i] = p.y();
    z_[i] = p.z();
    original_index_[i] = keyed[i].second;
    if (cells_.empty() || cells_.back().key != keyed[i].first) {
      cells_.push_back({keyed[i].first, static_cast<uint32_t>(i), static_cast<uint32_t>(i)});
    }
    cells_.back().end = static_cast<uint32_t>(i + 1);
  }
  std::vector<Range> columns;
  for (size_t c = 0; c < cells_.size(); ++c) {
    const uint64_t column = cells_[c].key & ~static_cast<uint64_t>(kMaxCell);
    if (columns.empty() || columns.back().key != column) {
      columns.push_back({column, static_cast<uint32_t>(c), static_cast<uint32_t>(c)});
    }
    columns.back().end = static_cast<uint32_t>(c + 1);
  }
  size_t table_size = 16;
  table_shift_ = 60;
  while (table_size < 2 * columns.size()) {
    table_size *= 2;
    --table_shift_;
  }
  columns_.assign(table_size, Range{kEmptyKey, 0, 0});
  table_mask_ = table_size - 1;
  for (const Range& column : columns) {
    uint64_t slot = slotOf(column.key);
    while (columns_[slot].key != kEmptyKey) slot = (slot + 1) & table_mask_;
    columns_[slot] = column;
  }
}

const NeighbourGrid::Range* NeighbourGrid::findColumn(uint64_t column_key) const {
  if (cells_.empty()) return nullptr;
  // The table holds the ranges themselves, so a lookup touches one cache line.
  for (uint64_t slot = slotOf(column_key);; slot = (slot + 1) & table_mask_) {
    const Range& r = columns_[slot];
    if (r.key == column_key) return &r;
    if (r.key == kEmptyKey) return nullptr;
  }
}

int NeighbourGrid::span(float radius) const {
  const double cells = std::ceil(static_cast<double>(radius) * inverse_cell_);
  // A query anywhere in its cell reaches at most ceil(r / cell) cells to each side.
  return static_cast<int>(std::clamp(cells, 1.0, static_cast<double>(kMaxCell)));
}

template <class Visit>
void NeighbourGrid::forEachColumnNear(int64_t cx, int64_t cy, int s, Visit&& visit) const {
  for (int64_t x = std::max<int64_t>(0, cx - s); x <= std::min<int64_t>(kMaxCell, cx + s); ++x) {
    for (int64_t y = std::max<int64_t>(0, cy - s); y <= std::min<int64_t>(kMaxCell, cy + s); ++y) {
      const Range* column = findColumn(keyOf(x, y, 0));
      if (column != nullptr) visit(*column);
    }
  }
}

template <class Visit>
void NeighbourGrid::forEachCellOfColumn(const Range& column, int64_t cz, int s, Visit&& visit) const {
  const uint64_t column_key = column.key;
  const uint64_t z_first = column_key | static_cast<uint64_t>(std::max<int64_t>(0, cz - s));
  const uint64_t z_last = column_key | static_cast<uint64_t>(std::min<int64_t>(kMaxCell, cz + s));
  // A column seen edge-on (a floor receding from the sensor) holds many cells: search, do not scan.
  const auto first = std::lower_bound(cells_.begin() + column.begin, cells_.begin() + column.end, z_first,
                                      [](const Range& cell, uint64_t key) { return cell.key < key; });
  for (auto cell = first; cell != cells_.begin() + column.end && cell->key <= z_last; ++cell) visit(*cell);
}

template <class Visit>
void NeighbourGrid::forEachCellNear(int64_t cx, int64_t cy, int64_t cz, int s, Visit&& visit) const {
  forEachColumnNear(cx, cy, s, [&](const Range& column) { forEachCellOfColumn(column, cz, s, visit); });
}

template <class Visit>
void NeighbourGrid::forEachCellAround(const Eigen::Vector3f& query, float radius, Visit&& visit) const {
  const int s = span(radius);
  // A radius spanning more cells than are occupied is cheaper to answer by visiting them all
  // (k-nearest searches far from the cloud grow their radius that far).
  const double visited = std::pow(2.0 * s + 1.0, 3.0);
  if (visited > static_cast<double>(cells_.size())) {
    for (const Range& range : cells_) visit(range);
    return;
  }
  const Eigen::Array3i c = cellOf(query);
  forEachCellNear(c.x(), c.y(), c.z(), s, visit);
}

size_t NeighbourGrid::radiusSearch(const Eigen::Vector3f& query, float radius, std::vector<int>& indices,
                                   std::vector<float>& squared_distances, size_t max_results) const {
  indices.clear();
  squared_distances.clear();
  if (cells_.empty() || !(radius >= 0.0f) || !query.allFinite()) return 0;
  const float r2 = radius * radius;
  if (max_results > 0) {
    bool full = false;
    forEachCellAround(query, radius, [&](const Range& range) {
      for (uint32_t i = range.begin; i < range.end && !full; ++i) {
        const float d2 = squaredDistance(i, query);
        if (d2 > r2) continue;
        indices.push_back(original_index_[i]);
        squared_distances.push_back(d2);
        full = indices.size() >= max_results;
      }
    });
    return indices.size();
  }
  // Branch-free compaction, as in forEachPoint.
  size_t found = 0;
  forEachCellAround(query, radius, [&](const Range& range) {
    indices.resize(found + (range.end - range.begin));
    squared_distances.resize(indices.size());
    for (uint32_t i = range.begin; i < range.end; ++i) {
      const float d2 = squaredDistance(i, query);
      indices[found] = original_index_[i];
      squared_distances[found] = d2;
      found += d2 <= r2;
    }
  });
  indices.resize(found);
  squared_distances.resize(found);
  return found;
}

std::vector<uint8_t> NeighbourGrid::pointsWithin(const std::vector<Eigen::Vector3f>& queries, float radius) const {
  const size_t n = original_index_.size();
  std::vector<uint8_t> flags(n, 0);
  if (cells_.empty() || !(radius >= 0.0f)) return flags;
  const float r2 = radius * radius;
  const int s = span(radius);
  // The queries by cell: those in one cell share the cells around it. Looking those up is
  // most of a search (49 columns at 8 cm in 3 cm cells), and contour keypoints come 2-3 a cell.
  std::vector<std::pair<uint64_t, int>> keyed;
  keyed.reserve(queries.size());
  for (size_t q = 0; q < queries.size(); ++q) {
    if (!queries[q].allFinite()) continue;
    const Eigen::Array3i c = cellOf(queries[q]);
    keyed.emplace_back(keyOf(c.x(), c.y(), c.z()), static_cast<int>(q));
  }
  sortByKey(keyed);
  std::vector<size_t> group_begin;
  for (size_t k = 0; k < keyed.size(); ++k) {
    if (k == 0 || keyed[k].first != keyed[k - 1].first) group_begin.push_back(k);
  }
  group_begin.push_back(keyed.size());

  // Whole cells are decided by their box where that is exact: a cell whose box is beyond the
  // radius of every query holds no point within it, one whose box is within the radius of a
  // query holds only such points, and one whose points are all marked needs no more tests. The
  // balls around contour keypoints a centimetre apart overlap almost entirely, so most cells
  // are decided once, and only the points of cells on the union's surface are tested one by
  // one. The box tests keep a margin of 1e-5 r^2, far above the rounding of the float test
  // point by point (a few 1e-7 relative), so that they agree with it. They are left to that
  // test in clamped cells (whose points may lie outside their box), for radii whose square is
  // not a normal float, and when every cell is visited (as radiusSearch then does).
  const double cell = static_cast<double>(cell_size_);
  const double inner2 = static_cast<double>(radius) * radius * (1.0 - 1e-5);
  const double outer2 = static_cast<double>(radius) * radius * (1.0 + 1e-5);
  const bool every_cell = std::pow(2.0 * s + 1.0, 3.0) > static_cast<double>(cells_.size());
  const bool boxes = !every_cell && r2 >= 1e-30f;
  const size_t side = 2 * static_cast<size_t>(s) + 1;  // cells per axis around a group's cell
  std::vector<uint8_t> marked(n, 0);                   // in the grid's order
#pragma omp parallel
  {
    // Per thread, merged after: flags are bytes that threads may not share.
    std::vector<uint8_t> mine(n, 0), complete(cells_.size(), 0);
    // Per query of the group, axis and cell offset: the least and the greatest squared distance
    // along that axis from the query to the cell's slab.
    std::vector<double> slab;
    std::vector<int> reaching;  // the queries of the group that may reach the current cell
#pragma omp for schedule(dynamic, 4) nowait
    for (std::ptrdiff_t g = 0; g < static_cast<std::ptrdiff_t>(group_begin.size()) - 1; ++g) {
      const size_t first = group_begin[static_cast<size_t>(g)], last = group_begin[static_cast<size_t>(g) + 1];
      const std::array<int64_t, 3> home = cellOfKey(keyed[first].first);
      if (boxes) {
        slab.resize((last - first) * 3 * side * 2);
        for (size_t q = first; q < last; ++q) {
          const Eigen::Vector3f& query = queries[static_cast<size_t>(keyed[q].second)];
          for (int a = 0; a < 3; ++a) {
            for (size_t o = 0; o < side; ++o) {
              // The slab, widened far beyond the rounding of the points' floor(p / cell).
              const double corner = (static_cast<double>(home[a] + static_cast<int64_t>(o) - s) + first_cell_[a]) * cell;
              const double margin = 1e-6 * (cell + std::abs(corner));
              const double low = corner - margin, high = corner + cell + margin, v = query[a];
              const double least = std::max({0.0, low - v, v - high});
              const double most = std::max(std::abs(v - low), std::abs(v - high));
              double* out = &slab[(((q - first) * 3 + static_cast<size_t>(a)) * side + o) * 2];
              out[0] = least * least;
              out[1] = most * most;
            }
          }
        }
      }
      const auto visit = [&](const Range& range) {
        const auto c = static_cast<size_t>(&range - cells_.data());
        if (complete[c]) return;
        const std::array<int64_t, 3> at = cellOfKey(range.key);
        const bool clamped = std::any_of(at.begin(), at.end(), [](int64_t v) { return v == 0 || v == kMaxCell; });
        reaching.clear();
        for (size_t q = first; q < last; ++q) {
          if (boxes && !clamped) {
            const double* t = &slab[(q - first) * 3 * side * 2];
            const double* x = t + static_cast<size_t>(at[0] - home[0] + s) * 2;
            const double* y = t + (side + static_cast<size_t>(at[1] - home[1] + s)) * 2;
            const double* z = t + (2 * side + static_cast<size_t>(at[2] - home[2] + s)) * 2;
            if (x[0] + y[0] + z[0] > outer2) continue;  // the cell is beyond this query
            if (x[1] + y[1] + z[1] <= inner2) {         // the cell is within its radius
              std::fill(mine.begin() + range.begin, mine.begin() + range.end, uint8_t{1});
              complete[c] = 1;
              return;
            }
          }
          reaching.push_back(keyed[q].second);
        }
        if (reaching.empty()) return;
        bool all = true;
        for (uint32_t j = range.begin; j < range.end; ++j) {
          for (size_t k = 0; k < reaching.size() && !mine[j]; ++k) {
            mine[j] = squaredDistance(j, queries[static_cast<size_t>(reaching[k])]) <= r2;
          }
          all = all && mine[j];
        }
        complete[c] = all;
      };
      if (every_cell) {
        for (const Range& range : cells_) visit(range);
      } else {
        forEachCellNear(home[0], home[1], home[2], s, visit);
      }
    }
#pragma omp critical(ism_points_within)
    for (size_t j = 0; j < n; ++j) marked[j] |= mine[j];
  }
  for (size_t j = 0; j < n; ++j) flags[static_cast<size_t>(original_index_[j])] = marked[j];
  return flags;
}

size_t NeighbourGrid::candidates(const Eigen::Vector3f& query, float radius) const {
  size_t n = 0;
  if (cells_.empty() || !(radius >= 0.0f) || !query.allFinite()) return n;
  forEachCellAround(query, radius, [&](const Range& range) { n += range.end - range.begin; });
  return n;
}

int NeighbourGrid::nearest(const Eigen::Vector3f& query, float max_distance,
                           const std::vector<uint8_t>* allowed) const {
  if (cells_.empty() || !(max_distance >= 0.0f) || !query.allFinite()) return -1;
  if (allowed != nullptr && allowed->size() != original_index_.size()) {
    throw Error(ErrorCode::kInternal, "NeighbourGrid::nearest: " + std::to_string(allowed->size()) +
                                          " flags for " + std::to_string(original_index_.size()) + " points");
  }
  float best = max_distance * max_distance;
  int best_index = -1;
  forEachCellAround(query, max_distance, [&](const Range& range) {
    for (uint32_t i = range.begin; i < range.end; ++i) {
      const float d2 = squaredDistance(i, query);
      if (d2 > best || (allowed != nullptr && !(*allowed)[static_cast<size_t>(original_index_[i])])) continue;
      // Ties go to the lower original index so that the answer does not depend on cell order.
      if (d2 < best || best_index < 0 || original_index_[i] < best_index) {
        best = d2;
        best_index = original_index_[i];
      }
    }
  });
  return best_index;
}

template <class Scratch, class Visit>
void NeighbourGrid::visitNeighbourhoods(float radius, const std::vector<uint8_t>* only, Visit&& visit) const {
  if (!(radius >= 0.0f)) {
    throw Error(ErrorCode::kInvalidInput, "neighbour search radius " + std::to_string(radius) + " must be >= 0");
  }
  if (only != nullptr && only->size() != original_index_.size()) {
    throw Error(ErrorCode::kInternal, "NeighbourGrid::forEachPoint: " + std::to_string(only->size()) +
                                          " flags for " + std::to_string(original_index_.size()) + " points");
  }
  const auto wanted = [&](uint32_t i) { return only == nullptr || (*only)[static_cast<size_t>(original_index_[i])]; };
  const float r2 = radius * radius;
  const int s = span(radius);
#pragma omp parallel
  {
    std::vector<const Range*> columns;  // the columns around the column of...
    uint64_t columns_around = kEmptyKey;  // ...this one
    std::vector<Quad> quads;
    std::vector<uint64_t> within;
    std::vector<uint32_t> inside;
    Neighbourhood neighbours;
    neighbours.x_ = x_.data();
    neighbours.y_ = y_.data();
    neighbours.z_ = z_.data();
    neighbours.index_ = original_index_.data();
    Scratch scratch;
#pragma omp for schedule(dynamic, 64)
    for (std::ptrdiff_t cell = 0; cell < static_cast<std::ptrdiff_t>(cells_.size()); ++cell) {
      const Range& home = cells_[static_cast<size_t>(cell)];
      bool any = false;
      for (uint32_t i = home.begin; i < home.end && !any; ++i) any = wanted(i);
      if (!any) continue;
      // The cells around this one are looked up once for all of its points, and the columns
      // around its column once for all cells of the column (they come one after the other).
      const std::array<int64_t, 3> c = cellOfKey(home.key);
      const uint64_t column_key = home.key & ~static_cast<uint64_t>(kMaxCell);
      if (column_key != columns_around) {
        columns.clear();
        forEachColumnNear(c[0], c[1], s, [&](const Range& column) { columns.push_back(&column); });
        columns_around = column_key;
      }
      // The cells' points lie in a few runs of the sorted arrays, which each point's distance
      // loop reads in quads: a loop per cell (of a few points) ran mostly in its vector remainder.
      quads.clear();
      uint32_t run_begin = 0, run_end = 0;
      for (const Range* column : columns) {
        forEachCellOfColumn(*column, c[2], s, [&](const Range& range) {
          if (range.begin != run_end) {
            appendRun(run_begin, run_end, quads);
            run_begin = range.begin;
          }
          run_end = range.end;
        });
      }
      appendRun(run_begin, run_end, quads);
      if (inside.size() < 4 * quads.size()) {  // only grows: no zero-filling per cell
        inside.resize(4 * quads.size());
        within.resize((quads.size() + 15) / 16);
      }
      neighbours.at_ = inside.data();
      for (uint32_t i = home.begin; i < home.end; ++i) {
        if (!wanted(i)) continue;
        const float p[3] = {x_[i], y_[i], z_[i]};
        markWithin(x_.data(), y_.data(), z_.data(), quads, p, r2, within.data());
        neighbours.size_ = pointsOf(within.data(), quads, inside.data());
        neighbours.centre_ = i;
        visit(original_index_[i], neighbours, scratch);
      }
    }
  }
}

void NeighbourGrid::forEachPoint(float radius, const std::function<void(int, const std::vector<int>&)>& visit,
                                 const std::vector<uint8_t>* only) const {
  const auto listed = [&](int i, const Neighbourhood& neighbours, std::vector<int>& list) {
    list.resize(neighbours.size());
    for (size_t k = 0; k < neighbours.size(); ++k) list[k] = neighbours.index(k);
    visit(i, list);
  };
  visitNeighbourhoods<std::vector<int>>(radius, only, listed);
}

void NeighbourGrid::forEachNeighbourhood(float radius, const std::function<void(int, const Neighbourhood&)>& visit,
                                         const std::vector<uint8_t>* only) const {
  struct None {};
  visitNeighbourhoods<None>(radius, only, [&](int i, const Neighbourhood& neighbours, None&) { visit(i, neighbours); });
}

template <class PointT>
void GridSearch<PointT>::setInputCloud(const PointCloudConstPtr& cloud, const pcl::IndicesConstPtr& indices) {
  this->input_ = cloud;
  this->indices_ = indices;
  subset_.clear();
  std::vector<Eigen::Vector3f> points;
  if (indices) {
    subset_ = *indices;
    points.reserve(indices->size());
    for (auto i : *indices) points.push_back((*cloud)[i].getVector3fMap());
  } else if (cloud) {
    points.reserve(cloud->size());
    for (const auto& p : *cloud) points.push_back(p.getVector3fMap());
  }
  grid_ = NeighbourGrid(std::move(points), cell_size_);
}

template <class PointT>
int GridSearch<PointT>::search(const PointT& point, double radius, pcl::Indices& k_indices,
                               std::vector<float>& k_sqr_distances, unsigned int max_nn, bool sort) const {
  std::vector<int> found;
  grid_.radiusSearch(point.getVector3fMap(), static_cast<float>(radius), found, k_sqr_distances, max_nn);
  k_indices.assign(found.begin(), found.end());
  if (!subset_.empty()) {
    for (auto& i : k_indices) i = subset_[static_cast<size_t>(i)];
  }
  if (sort) {
    std::vector<size_t> order(k_indices.size());
    std::iota(order.begin(), order.end(), size_t{0});
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
      return k_sqr_distances[a] < k_sqr_distances[b] || (k_sqr_distances[a] == k_sqr_distances[b] && k_indices[a] < k_indices[b]);
    });
    pcl::Indices sorted_indices(order.size());
    std::vector<float> sorted_distances(order.size());
    for (size_t i = 0; i < order.size(); ++i) {
      sorted_indices[i] = k_indices[order[i]];
      sorted_distances[i] = k_sqr_distances[order[i]];
    }
    k_indices.swap(sorted_indices);
    k_sqr_distances.swap(sorted_distances);
  }
  return static_cast<int>(k_indices.size());
}

template <class PointT>
int GridSearch<PointT>::radiusSearch(const PointT& point, double radius, pcl::Indices& k_indices,
                                     std::vector<float>& k_sqr_distances, unsigned int max_nn) const {
  return search(point, radius, k_indices, k_sqr_distances, max_nn, /*sort=*/false);
}

template <class PointT>
int GridSearch<PointT>::nearestKSearch(const PointT& point, int k, pcl::Indices& k_indices,
                                       std::vector<float>& k_sqr_distances) const {
  k_indices.clear();
  k_sqr_distances.clear();
  if (k <= 0 || grid_.size() == 0 || !point.getVector3fMap().allFinite()) return 0;
  const size_t wanted = std::min(static_cast<size_t>(k), grid_.size());
  // Doubling the radius until k points are inside finds the k nearest: any point outside the
  // final radius is farther than all those inside it. Past the cloud's extent the grid visits
  // every cell, so the loop ends once the radius covers the distance to the farthest point.
  for (double radius = grid_.cellSize();; radius *= 2.0) {
    search(point, radius, k_indices, k_sqr_distances, 0, /*sort=*/true);
    if (k_indices.size() >= wanted || !std::isfinite(radius * 2.0)) break;
  }
  const size_t n = std::min(wanted, k_indices.size());
  k_indices.resize(n);
  k_sqr_distances.resize(n);
  return static_cast<int>(n);
}

template class GridSearch<pcl::PointNormal>;
template class GridSearch<pcl::PointXYZ>;

}  // namespace ism
