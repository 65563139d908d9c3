#pragma once
// The cells of a hypothesis' inner footprint, in which the scene checks count measured points
// (under_top.h, seat_area.h, bare_floor.h): the footprint's sides shrunk to `inner` of theirs, so
// that a neighbour's or the object's own edge stays out, and split into whole cells of at most
// `cell`, x-major. Coordinates are about the footprint's centre along its sides (SceneBox::boxFrame).
#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/Core>

namespace ism {

struct FootprintCells {
  float width = 0, depth = 0;  // the inner footprint (m)
  int nx = 1, ny = 1;

  FootprintCells(float box_width, float box_depth, float inner, float cell)
      : width(inner * box_width), depth(inner * box_depth) {
    if (!degenerate()) {
      nx = std::max(1, static_cast<int>(std::ceil(width / cell)));
      ny = std::max(1, static_cast<int>(std::ceil(depth / cell)));
    }
  }
  // No footprint to look at: nothing lies in it.
  bool degenerate() const { return !(width > 0 && depth > 0); }
  std::size_t size() const { return static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny); }
  // The cell holding (x, y), or -1 outside the inner footprint.
  int of(float x, float y) const {
    if (degenerate()) return -1;
    const float u = (x + width / 2) / width, v = (y + depth / 2) / depth;
    if (!(u >= 0 && u < 1 && v >= 0 && v < 1)) return -1;
    return static_cast<int>(u * static_cast<float>(nx)) * ny + static_cast<int>(v * static_cast<float>(ny));
  }
  // The middle of cell `i`.
  Eigen::Vector2f middle(int i) const {
    return {-width / 2 + (static_cast<float>(i / ny) + 0.5f) * width / static_cast<float>(nx),
            -depth / 2 + (static_cast<float>(i % ny) + 0.5f) * depth / static_cast<float>(ny)};
  }
};

}  // namespace ism
