#include "core/recognition/box_selection.h"

#include <Eigen/Eigenvalues>
#include <limits>

namespace ism {

OrientedBox fitOrientedBox(const std::vector<Eigen::Vector3f>& points) {
  OrientedBox box;
  if (points.empty()) return box;
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<float>(points.size());
  Eigen::Matrix3f covariance = Eigen::Matrix3f::Zero();
  for (const auto& p : points) covariance += (p - mean) * (p - mean).transpose();
  Eigen::Matrix3f axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f>(covariance).eigenvectors();
  if (axes.determinant() < 0) axes.col(0) = -axes.col(0);  // keep a proper rotation
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3f local = axes.transpose() * (p - mean);
    lo = lo.cwiseMin(local);
    hi = hi.cwiseMax(local);
  }
  box.size = hi - lo;
  box.center = mean + axes * ((lo + hi) / 2);
  box.rotation = Eigen::Quaternionf(axes).normalized();
  return box;
}

bool passesBoxSelection(const OrientedBox& box, const BoxStats& stats) {
  const float volume = box.volume();
  return volume >= stats.min_volume && volume <= stats.max_volume && box.longestEdge() <= stats.max_edge;
}

}  // namespace ism
