#include "core/frontend/occluding_contours.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <string>

#include "core/common/error.h"
#include "core/frontend/param_checks.h"

namespace ism {
namespace {

// Pixels with no return (no point, or a point whose range is NaN) hold this. Ranges are norms,
// so never negative: the nearest of a pixel's neighbours is negative exactly when one of them
// has no return, and that one comparison sends a pixel from the per-row formula to the full
// test.
constexpr float kNoReturn = -1.0f;
bool hasReturn(float range) { return range >= 0.0f; }

constexpr int kContourDirections[8][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}};

// ContourParams' test of one pixel, valid anywhere in the image: along each direction, the
// pixels up to `window` away that are inside the image decide; when none of them has a
// return, the first one with a return within max_gap does, and when there is none either, it
// is a silhouette against empty space unless the image ended before max_gap.
bool isOccludingContourPixel(const std::vector<float>& range, int width, int height, int row, int col,
                             const ContourParams& params) {
  const float* center = &range[static_cast<size_t>(row) * width + col];
  const float r = *center;
  if (!hasReturn(r)) return false;
  const float jump = std::max(params.min_jump, params.relative_jump * r);
  bool occluding = false, shadow = false;
  constexpr int kNoBorder = std::numeric_limits<int>::max();
  for (const auto& d : kContourDirections) {
    // Steps along d that stay inside the image.
    const int inside = std::min(d[0] > 0 ? width - 1 - col : d[0] < 0 ? col : kNoBorder,
                                d[1] > 0 ? height - 1 - row : d[1] < 0 ? row : kNoBorder);
    const int last = std::min(params.max_gap, inside);
    const std::ptrdiff_t stride = d[1] * static_cast<std::ptrdiff_t>(width) + d[0];
    bool seen = false;
    int step = 1;
    // Without branches on the data: which of these pixels have a return is unpredictable.
    for (const int window_end = std::min(params.window, last); step <= window_end; ++step) {
      const float other = center[step * stride];
      const bool returned = hasReturn(other);
      seen |= returned;
      occluding |= returned & (other - r > jump);
      shadow |= returned & (r - other > jump);
    }
    for (; !seen && step <= last; ++step) {
      const float other = center[step * stride];
      if (hasReturn(other)) {
        seen = true;
        occluding |= other - r > jump;
        shadow |= r - other > jump;
      }
    }
    // No return all the way across the gap: a silhouette against empty space.
    occluding |= !seen && inside >= params.max_gap;
  }
  return occluding && !shadow;
}

// Folds the 8 pixels `step` away from each pixel in [begin, end) of the row `center` into
// `nearest` and `farthest`. A function of its own so that __restrict can tell GCC the outputs
// are not the range image: otherwise the loop would need 16 run-time alias checks, and above
// 10 (--param vect-max-version-for-alias-checks) GCC does not vectorise it.
void foldContourNeighbours(const float* center, std::ptrdiff_t width, int step, int begin, int end,
                           float* __restrict nearest, float* __restrict farthest) {
  const float* neighbour[8];
  for (int k = 0; k < 8; ++k) {
    neighbour[k] = center + step * (kContourDirections[k][1] * width + kContourDirections[k][0]);
  }
  for (int col = begin; col < end; ++col) {
    float lo = nearest[col], hi = farthest[col];
    for (int k = 0; k < 8; ++k) {
      lo = std::min(lo, neighbour[k][col]);
      hi = std::max(hi, neighbour[k][col]);
    }
    nearest[col] = lo;
    farthest[col] = hi;
  }
}

}  // namespace

std::vector<int> detectOccludingContourPixels(const Scene& scene, const ContourParams& params) {
  requireAtLeast(params.window, 1, "keypoints.contour.window");
  requireAtLeast(params.max_gap, params.window, "keypoints.contour.max_gap (at least the window)");
  requirePositive(params.min_jump, "keypoints.contour.min_jump");
  if (!(params.relative_jump >= 0.0f && std::isfinite(params.relative_jump))) {
    throw Error(ErrorCode::kInvalidInput, "front end parameter keypoints.contour.relative_jump = " +
                                              std::to_string(params.relative_jump) + " must be >= 0 and finite");
  }
  const int width = scene.image_width, height = scene.image_height;
  const size_t pixels = static_cast<size_t>(std::max(width, 0)) * static_cast<size_t>(std::max(height, 0));
  if (scene.pixel_index.empty() || pixels == 0 || !scene.cloud || scene.pixel_index.size() != scene.cloud->size()) {
    throw Error(ErrorCode::kInvalidInput,
                scene.source + ": occluding-contour keypoints need an organized scene (a depth image or an organized "
                               "cloud), got " + std::to_string(width) + "x" + std::to_string(height) + " pixels and " +
                               std::to_string(scene.pixel_index.size()) + " pixel indices for " +
                               std::to_string(scene.cloud ? scene.cloud->size() : 0) + " points");
  }
  std::vector<float> range(pixels, kNoReturn);
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    const int pixel = scene.pixel_index[i];
    if (pixel < 0 || static_cast<size_t>(pixel) >= pixels) {
      throw Error(ErrorCode::kInvalidInput, scene.source + ": pixel index " + std::to_string(pixel) + " is outside the " +
                                                std::to_string(width) + "x" + std::to_string(height) + " image");
    }
    const float r = ((*scene.cloud)[i].getVector3fMap() - scene.sensor_origin).norm();
    range[pixel] = std::isnan(r) ? kNoReturn : r;
  }
  // Most pixels have all 8 * window neighbours inside the image and with a return. Their scan
  // stops at the window in every direction, and an edge is then "some neighbour farther than
  // r + jump, none nearer than r - jump". A rounded subtraction never reverses an order, so
  // comparing the farthest and the nearest neighbour decides, and finding those vectorises
  // over whole rows. The other pixels (the image border, next to a hole) take the full test.
  const int window = params.window;
  const float min_jump = params.min_jump, relative_jump = params.relative_jump;
  std::vector<uint8_t> is_edge(pixels, 0);
#pragma omp parallel
  {
    // Each thread's buffers for its current row.
    std::vector<float> nearest(static_cast<size_t>(width)), farthest(static_cast<size_t>(width));
    std::vector<uint8_t> look_across(static_cast<size_t>(width));
#pragma omp for schedule(dynamic, 16)
    for (int row = 0; row < height; ++row) {
      const float* row_range = &range[static_cast<size_t>(row) * width];
      uint8_t* row_edge = &is_edge[static_cast<size_t>(row) * width];
      // Columns [begin, end) have their whole window inside the image.
      const bool inner_row = row >= window && row < height - window;
      const int begin = inner_row ? std::min(window, width) : width;
      const int end = inner_row ? std::max(begin, width - window) : width;
      std::fill(nearest.begin() + begin, nearest.begin() + end, std::numeric_limits<float>::infinity());
      std::fill(farthest.begin() + begin, farthest.begin() + end, -std::numeric_limits<float>::infinity());
      for (int step = 1; step <= window; ++step) {
        foldContourNeighbours(row_range, width, step, begin, end, nearest.data(), farthest.data());
      }
      for (int col = begin; col < end; ++col) {
        const float r = row_range[col];
        const float jump = std::max(min_jump, relative_jump * r);
        row_edge[col] = hasReturn(r) & (farthest[col] - r > jump) & !(r - nearest[col] > jump);
        look_across[col] = hasReturn(r) & !hasReturn(nearest[col]);
      }
      // Few pixels look across a hole (5% of those with a return on tum_desk): memchr finds
      // them faster than a loop testing every flag.
      const uint8_t* const flags = look_across.data();
      for (const uint8_t* p = flags + begin; p < flags + end; ++p) {
        p = static_cast<const uint8_t*>(std::memchr(p, 1, static_cast<size_t>(flags + end - p)));
        if (p == nullptr) break;
        const int col = static_cast<int>(p - flags);
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
      for (int col = 0; col < begin; ++col) {
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
      for (int col = end; col < width; ++col) {
        row_edge[col] = isOccludingContourPixel(range, width, height, row, col, params);
      }
    }
  }
  std::vector<int> edges;
  for (size_t i = 0; i < scene.pixel_index.size(); ++i) {
    if (is_edge[scene.pixel_index[i]]) edges.push_back(static_cast<int>(i));
  }
  return edges;
}

}  // namespace ism
