#pragma once
// Fixed-radius neighbour search over a cloud that does not change, for the front end's
// surface-sized searches (MLS at 2 cm, normals at 3 cm, SHOT at 8 cm over 1 cm voxels).
//
// Why not PCL's FLANN k-d tree: building trees and walking them is most of the front end's
// single-core time on a 640x480 Kinect frame (perf on tum_desk). Points here are voxel
// centroids, so a uniform grid with cells as large as the search radius holds a bounded number
// of points per cell, a query visits the 27 cells around it, and when every point is a query
// the cells' neighbourhoods are gathered once per cell instead of once per point.
#include <pcl/point_cloud.h>
#include <pcl/search/search.h>

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ism {

class NeighbourGrid {
 public:
  NeighbourGrid() = default;
  // `cell_size` should be the radius most queries use: smaller radii still work, larger ones
  // visit more cells. Throws ism::Error unless it is positive and finite.
  template <class PointT>
  NeighbourGrid(const pcl::PointCloud<PointT>& cloud, float cell_size) {
    std::vector<Eigen::Vector3f> points(cloud.size());
    for (size_t i = 0; i < cloud.size(); ++i) points[i] = cloud[i].getVector3fMap();
    build(std::move(points), cell_size);
  }
  NeighbourGrid(std::vector<Eigen::Vector3f> points, float cell_size) { build(std::move(points), cell_size); }

  size_t size() const { return original_index_.size(); }
  float cellSize() const { return cell_size_; }

  // Indices (into the cloud given at construction, in no particular order) and squared
  // distances of the points within `radius` of `query`; with max_results > 0 it stops after that
  // many. Returns the count. Not sorted by distance: none of the front end's users need it.
  size_t radiusSearch(const Eigen::Vector3f& query, float radius, std::vector<int>& indices,
                      std::vector<float>& squared_distances, size_t max_results = 0) const;

  // Per cloud point, 1 when it is within `radius` of one of `queries`: the union of their
  // radiusSearch results (non-finite queries find nothing). In parallel over OpenMP's threads.
  std::vector<uint8_t> pointsWithin(const std::vector<Eigen::Vector3f>& queries, float radius) const;

  // How many points a search of `radius` around `query` compares: the cost of one search.
  size_t candidates(const Eigen::Vector3f& query, float radius) const;

  // The nearest point within `max_distance` of `query`, or -1. With `allowed`, only points i with
  // allowed[i] != 0 count.
  int nearest(const Eigen::Vector3f& query, float max_distance, const std::vector<uint8_t>* allowed = nullptr) const;

  // Calls visit(i, neighbours) for every point i of the cloud (with `only`, those with only[i] != 0)
  // with the indices of the points within `radius` of it (i itself included), in parallel over
  // OpenMP's threads. `visit` must be safe to call concurrently for different i. The neighbour list
  // is only valid during the call. The order of the list is fixed by the cell size and the points
  // (cells in ascending x, y, z, then cloud order within a cell), as radiusSearch's is.
  void forEachPoint(float radius, const std::function<void(int, const std::vector<int>&)>& visit,
                    const std::vector<uint8_t>* only = nullptr) const;

  // One point's neighbours as forEachPoint lists them, with their coordinates: neighbour k
  // (k < size()) is cloud point index(k) at (x(k), y(k), z(k)), the coordinates the grid was
  // built from; point() is the visited point's. Valid only during the visit.
  class Neighbourhood {
   public:
    Eigen::Vector3f point() const { return {x_[centre_], y_[centre_], z_[centre_]}; }
    size_t size() const { return size_; }
    int index(size_t k) const { return index_[at_[k]]; }
    float x(size_t k) const { return x_[at_[k]]; }
    float y(size_t k) const { return y_[at_[k]]; }
    float z(size_t k) const { return z_[at_[k]]; }

   private:
    friend class NeighbourGrid;
    const float *x_ = nullptr, *y_ = nullptr, *z_ = nullptr;  // the grid's arrays
    const int* index_ = nullptr;
    uint32_t centre_ = 0;           // the visited point's position in them
    const uint32_t* at_ = nullptr;  // the neighbours' positions in them
    size_t size_ = 0;
  };
  // forEachPoint for visitors that read the neighbours' coordinates (PCA normals): no index list
  // is built, and the coordinates come from the grid's arrays, where the neighbours lie close
  // together, rather than from all over the cloud.
  void forEachNeighbourhood(float radius, const std::function<void(int, const Neighbourhood&)>& visit,
                            const std::vector<uint8_t>* only = nullptr) const;

 private:
  struct Range {
    uint64_t key;
    uint32_t begin, end;  // cells_: into the sorted points; columns_: into cells_
  };
  void build(std::vector<Eigen::Vector3f> points, float cell_size);
  uint64_t keyOf(int64_t x, int64_t y, int64_t z) const;
  uint64_t slotOf(uint64_t key) const;
  Eigen::Array3i cellOf(const Eigen::Vector3f& p) const;
  const Range* findColumn(uint64_t column_key) const;
  // visit(range) for each occupied cell within `s` cells of cell (cx, cy, cz) on every axis, in
  // ascending key order (x, then y, then z).
  template <class Visit>
  void forEachCellNear(int64_t cx, int64_t cy, int64_t cz, int s, Visit&& visit) const;
  // Its two halves: visit(column) for each column within `s` of column (cx, cy), in ascending
  // key order, and visit(range) for each cell of `column` within `s` of cz on the z axis.
  template <class Visit>
  void forEachColumnNear(int64_t cx, int64_t cy, int s, Visit&& visit) const;
  template <class Visit>
  void forEachCellOfColumn(const Range& column, int64_t cz, int s, Visit&& visit) const;
  // The loop behind forEachPoint and forEachNeighbourhood: visit(original index, Neighbourhood,
  // scratch), with a Scratch per thread.
  template <class Scratch, class Visit>
  void visitNeighbourhoods(float radius, const std::vector<uint8_t>* only, Visit&& visit) const;
  // visit(range) for each occupied cell that may hold points within `radius` of `query`.
  template <class Visit>
  void forEachCellAround(const Eigen::Vector3f& query, float radius, Visit&& visit) const;
  int span(float radius) const;  // cells to look at on each side of the query's cell
  float squaredDistance(uint32_t i, const Eigen::Vector3f& q) const {
    const float dx = x_[i] - q.x(), dy = y_[i] - q.y(), dz = z_[i] - q.z();
    return dx * dx + dy * dy + dz * dz;
  }

  float cell_size_ = 1.0f;
  float inverse_cell_ = 1.0f;
  double inverse_cell_exact_ = 1.0;
  // Cell coordinates are floor(p / cell) - first_cell_, which puts the median point's cell at the
  // middle of the 21-bit range (double: ~10^6 cells away from the points).
  Eigen::Vector3d first_cell_ = Eigen::Vector3d::Zero();
  // The points ordered by cell, one array per coordinate so that distances to a run of them
  // vectorise; 3 zeros follow the last point.
  std::vector<float> x_, y_, z_;
  std::vector<int> original_index_;  // sorted point i was point original_index_[i]
  std::vector<Range> cells_;         // one per occupied cell, ascending key
  // A column is the cells sharing x and y; they are contiguous in cells_ and ascend in z. The
  // table is keyed by column, so the 27 cells around a cell cost 9 lookups instead of 27.
  std::vector<Range> columns_;  // open addressing (linear probing), key = keyOf(x, y, 0)
  uint64_t table_mask_ = 0;
  int table_shift_ = 60;  // 64 - log2(table size)
};

// NeighbourGrid behind PCL's search interface, so that PCL's estimators can use it in place of
// a k-d tree: shot_test runs PCL's SHOT and LRF over it to check computeShot(). k-nearest searches are answered by growing the radius until k
// points are found, and come sorted. Radius searches come unsorted, whatever setSortedResults()
// asked: pcl::SHOTLocalReferenceFrameEstimation asks for sorting on the search it shares with
// SHOT, yet neither reads the order (PCL 1.13 shot_lrf.hpp, shot.hpp), and sorting every 8 cm
// neighbourhood would cost 4% of a frame.
template <class PointT>
class GridSearch : public pcl::search::Search<PointT> {
 public:
  using PointCloudConstPtr = typename pcl::search::Search<PointT>::PointCloudConstPtr;
  explicit GridSearch(float cell_size) : pcl::search::Search<PointT>("NeighbourGrid", false), cell_size_(cell_size) {}

  void setInputCloud(const PointCloudConstPtr& cloud,
                     const pcl::IndicesConstPtr& indices = pcl::IndicesConstPtr()) override;
  void setSortedResults(bool) override {}
  int nearestKSearch(const PointT& point, int k, pcl::Indices& k_indices,
                     std::vector<float>& k_sqr_distances) const override;
  int radiusSearch(const PointT& point, double radius, pcl::Indices& k_indices, std::vector<float>& k_sqr_distances,
                   unsigned int max_nn = 0) const override;

 private:
  int search(const PointT& point, double radius, pcl::Indices& k_indices, std::vector<float>& k_sqr_distances,
             unsigned int max_nn, bool sort) const;

  float cell_size_;
  NeighbourGrid grid_;
  pcl::Indices subset_;  // the grid's point i is cloud point subset_[i] (when indices were given)
};

}  // namespace ism
