#include "core/frontend/neighbour_grid.h"

#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/common/error.h"
#include "core/common/hash.h"
#include "core/common/radix_sort.h"

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
  // always distinct. An origin at the minimum let one stray point (a smoothing fit gone wild, a
  // bogus point in a user's cloud) push every real point past the 21-bit range into a few
  // clamped cells, and the searches became quadratic: normals on a 640x480 frame took 17-29 s
  // instead of 0.1 s. Only points more than 2^20 cells from the median share clamped cells now.
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
  x_.resize(points.size());
  y_.resize(points.size());
  z_.resize(points.size());
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
void NeighbourGrid::forEachCellNear(int64_t cx, int64_t cy, int64_t cz, int s, Visit&& visit) const {
  const uint64_t z_first = static_cast<uint64_t>(std::max<int64_t>(0, cz - s));
  const uint64_t z_last = static_cast<uint64_t>(std::min<int64_t>(kMaxCell, cz + s));
  for (int64_t x = std::max<int64_t>(0, cx - s); x <= std::min<int64_t>(kMaxCell, cx + s); ++x) {
    for (int64_t y = std::max<int64_t>(0, cy - s); y <= std::min<int64_t>(kMaxCell, cy + s); ++y) {
      const uint64_t column_key = keyOf(x, y, 0);
      const Range* column = findColumn(column_key);
      if (column == nullptr) continue;
      // A column seen edge-on (a floor receding from the sensor) holds many cells: search, do not scan.
      const auto first = std::lower_bound(cells_.begin() + column->begin, cells_.begin() + column->end,
                                          column_key | z_first,
                                          [](const Range& cell, uint64_t key) { return cell.key < key; });
      for (auto cell = first; cell != cells_.begin() + column->end && cell->key <= (column_key | z_last); ++cell) {
        visit(*cell);
      }
    }
  }
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

void NeighbourGrid::forEachPoint(float radius, const std::function<void(int, const std::vector<int>&)>& visit,
                                 const std::vector<uint8_t>* only) const {
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
    std::vector<const Range*> around;
    std::vector<int> neighbours;
    std::vector<float> distances;
#pragma omp for schedule(dynamic, 64)
    for (std::ptrdiff_t cell = 0; cell < static_cast<std::ptrdiff_t>(cells_.size()); ++cell) {
      const Range& home = cells_[static_cast<size_t>(cell)];
      bool any = false;
      for (uint32_t i = home.begin; i < home.end && !any; ++i) any = wanted(i);
      if (!any) continue;
      // The cells around this one are looked up once for all of its points.
      around.clear();
      forEachCellNear(static_cast<int64_t>(home.key >> 42), static_cast<int64_t>((home.key >> 21) & kMaxCell),
                      static_cast<int64_t>(home.key & kMaxCell), s, [&](const Range& range) { around.push_back(&range); });
      size_t candidates = 0;
      for (const Range* range : around) candidates += range->end - range->begin;
      distances.resize(candidates);
      for (uint32_t i = home.begin; i < home.end; ++i) {
        if (!wanted(i)) continue;
        const float px = x_[i], py = y_[i], pz = z_[i];
        // Distances first, in a loop over contiguous coordinates that vectorises; then a
        // branch-free compaction: about half of the candidates are inside, so a branch on the
        // distance would be mispredicted half of the time.
        size_t n = 0;
        for (const Range* range : around) {
          for (uint32_t j = range->begin; j < range->end; ++j, ++n) {
            const float dx = x_[j] - px, dy = y_[j] - py, dz = z_[j] - pz;
            distances[n] = dx * dx + dy * dy + dz * dz;
          }
        }
        neighbours.resize(candidates);
        size_t found = 0;
        n = 0;
        for (const Range* range : around) {
          for (uint32_t j = range->begin; j < range->end; ++j, ++n) {
            neighbours[found] = original_index_[j];
            found += distances[n] <= r2;
          }
        }
        neighbours.resize(found);
        visit(original_index_[i], neighbours);
      }
    }
  }
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
