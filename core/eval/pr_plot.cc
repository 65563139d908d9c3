// The precision-recall curves of one evaluated strategy as a PNG: one line per ground-truth
// class, a legend with each class's AP@0.25, and a labelled unit square.
#include <png.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

#include "core/common/error.h"
#include "core/eval/eval.h"

namespace ism {
namespace {

// A 5x7 bitmap font for the few characters labels need; lower case is drawn as upper case and
// anything else as a blank.
const std::map<char, std::array<const char*, 7>>& glyphs() {
  static const std::map<char, std::array<const char*, 7>> font = {
      {'A', {".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}},
      {'B', {"####.", "#...#", "#...#", "####.", "#...#", "#...#", "####."}},
      {'C', {".###.", "#...#", "#....", "#....", "#....", "#...#", ".###."}},
      {'D', {"####.", "#...#", "#...#", "#...#", "#...#", "#...#", "####."}},
      {'E', {"#####", "#....", "#....", "####.", "#....", "#....", "#####"}},
      {'F', {"#####", "#....", "#....", "####.", "#....", "#....", "#...."}},
      {'G', {".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####"}},
      {'H', {"#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}},
      {'I', {".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}},
      {'J', {"..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##.."}},
      {'K', {"#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#"}},
      {'L', {"#....", "#....", "#....", "#....", "#....", "#....", "#####"}},
      {'M', {"#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#"}},
      {'N', {"#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"}},
      {'O', {".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}},
      {'P', {"####.", "#...#", "#...#", "####.", "#....", "#....", "#...."}},
      {'Q', {".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#"}},
      {'R', {"####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#"}},
      {'S', {".####", "#....", "#....", ".###.", "....#", "....#", "####."}},
      {'T', {"#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."}},
      {'U', {"#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}},
      {'V', {"#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#.."}},
      {'W', {"#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#."}},
      {'X', {"#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#"}},
      {'Y', {"#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#.."}},
      {'Z', {"#####", "....#", "...#.", "..#..", ".#...", "#....", "#####"}},
      {'0', {".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."}},
      {'1', {"..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."}},
      {'2', {".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"}},
      {'3', {"#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."}},
      {'4', {"...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."}},
      {'5', {"#####", "#....", "####.", "....#", "....#", "#...#", ".###."}},
      {'6', {"..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."}},
      {'7', {"#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."}},
      {'8', {".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."}},
      {'9', {".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."}},
      {'.', {".....", ".....", ".....", ".....", ".....", ".##..", ".##.."}},
      {',', {".....", ".....", ".....", ".....", ".##..", "..#..", ".#..."}},
      {':', {".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."}},
      {'%', {"##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"}},
      {'@', {".###.", "#...#", "#.###", "#.#.#", "#.###", "#....", ".####"}},
      {'|', {"..#..", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."}},
      {'-', {".....", ".....", ".....", "#####", ".....", ".....", "....."}},
      {'_', {".....", ".....", ".....", ".....", ".....", ".....", "#####"}},
      {'+', {".....", "..#..", "..#..", "#####", "..#..", "..#..", "....."}},
      {'/', {".....", "....#", "...#.", "..#..", ".#...", "#....", "....."}},
      {'(', {"...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#."}},
      {')', {".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#..."}},
      {'=', {".....", ".....", "#####", ".....", "#####", ".....", "....."}},
  };
  return font;
}

struct Rgb {
  uint8_t r, g, b;
};

class Image {
 public:
  Image(int width, int height) : width_(width), height_(height), pixels_(static_cast<size_t>(width) * height * 3, 255) {}

  void set(int x, int y, Rgb c) {
    if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
    uint8_t* p = &pixels_[(static_cast<size_t>(y) * width_ + x) * 3];
    p[0] = c.r;
    p[1] = c.g;
    p[2] = c.b;
  }

  // Bresenham, `thickness` pixels wide.
  void line(int x0, int y0, int x1, int y1, Rgb c, int thickness = 1) {
    const int dx = std::abs(x1 - x0), dy = -std::abs(y1 - y0);
    const int sx = x0 < x1 ? 1 : -1, sy = y0 < y1 ? 1 : -1;
    int err = dx + dy;
    for (;;) {
      for (int i = 0; i < thickness; ++i) {
        for (int j = 0; j < thickness; ++j) set(x0 + i - thickness / 2, y0 + j - thickness / 2, c);
      }
      if (x0 == x1 && y0 == y1) break;
      const int e2 = 2 * err;
      if (e2 >= dy) {
        err += dy;
        x0 += sx;
      }
      if (e2 <= dx) {
        err += dx;
        y0 += sy;
      }
    }
  }

  // Text with its top-left corner at (x, y), each font pixel `scale` pixels wide.
  void text(int x, int y, const std::string& s, Rgb c, int scale = 2) {
    for (char ch : s) {
      const auto it = glyphs().find(static_cast<char>(std::toupper(static_cast<unsigned char>(ch))));
      if (it != glyphs().end()) {
        for (int row = 0; row < 7; ++row) {
          for (int col = 0; col < 5; ++col) {
            if (it->second[static_cast<size_t>(row)][col] != '#') continue;
            for (int i = 0; i < scale; ++i) {
              for (int j = 0; j < scale; ++j) set(x + col * scale + i, y + row * scale + j, c);
            }
          }
        }
      }
      x += 6 * scale;
    }
  }

  std::string png() const {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(width_);
    image.height = static_cast<png_uint_32>(height_);
    image.format = PNG_FORMAT_RGB;
    png_alloc_size_t size = 0;
    if (!png_image_write_to_memory(&image, nullptr, &size, 0, pixels_.data(), 0, nullptr)) {
      throw Error(ErrorCode::kInternal, std::string("precision-recall plot: ") + image.message);
    }
    std::string bytes(size, '\0');
    if (!png_image_write_to_memory(&image, bytes.data(), &size, 0, pixels_.data(), 0, nullptr)) {
      throw Error(ErrorCode::kInternal, std::string("precision-recall plot: ") + image.message);
    }
    return bytes;
  }

 private:
  int width_, height_;
  std::vector<uint8_t> pixels_;
};

std::string percentText(double fraction) {
  if (std::isnan(fraction)) return "-";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  s << 100 * fraction << "%";
  return s.str();
}

}  // namespace

std::string renderPrecisionRecall(const RealCombination& combination) {
  constexpr int kWidth = 720, kHeight = 560, kLeft = 70, kTop = 50, kSide = 420;
  const Rgb black{0, 0, 0}, grey{215, 215, 215};
  static const Rgb palette[] = {{31, 119, 180}, {214, 39, 40}, {44, 160, 44}, {148, 103, 189}, {255, 127, 14},
                                {140, 86, 75},  {227, 119, 194}, {127, 127, 127}};
  Image image(kWidth, kHeight);
  const auto px = [&](double recall) { return kLeft + static_cast<int>(std::lround(recall * kSide)); };
  const auto py = [&](double precision) { return kTop + kSide - static_cast<int>(std::lround(precision * kSide)); };
  for (int i = 0; i <= 10; ++i) {
    const double t = i / 10.0;
    image.line(px(t), py(0), px(t), py(1), grey);
    image.line(px(0), py(t), px(1), py(t), grey);
    std::ostringstream label;
    label << t;
    if (i % 2 == 0) {
      image.text(px(t) - 8, py(0) + 8, label.str(), black);
      image.text(px(0) - 44, py(t) - 7, label.str(), black);
    }
  }
  image.line(px(0), py(0), px(1), py(0), black, 2);
  image.line(px(0), py(0), px(0), py(1), black, 2);
  image.text(px(0.5) - 36, py(0) + 30, "recall", black);
  image.text(8, kTop - 36, "precision", black);
  image.text(kLeft + 90, 10, combination.strategy + ": AP@0.25 (3D IOU)", black);

  int legend_y = kTop + 10;
  size_t colour = 0;
  for (const auto& k : combination.classes) {
    if (k.objects == 0) continue;
    const Rgb c = palette[colour++ % (sizeof palette / sizeof palette[0])];
    // A step curve: precision holds until the next detection.
    int x = px(0), y = py(k.pr25.empty() ? 0 : k.pr25.front().second);
    for (const auto& [recall, precision] : k.pr25) {
      image.line(x, y, px(recall), y, c, 3);
      image.line(px(recall), y, px(recall), py(precision), c, 3);
      x = px(recall);
      y = py(precision);
    }
    image.line(kLeft + kSide + 12, legend_y + 7, kLeft + kSide + 32, legend_y + 7, c, 3);
    image.text(kLeft + kSide + 38, legend_y, k.name, c);
    image.text(kLeft + kSide + 38, legend_y + 18, percentText(k.ap25), c);
    legend_y += 44;
  }
  return image.png();
}

}  // namespace ism
