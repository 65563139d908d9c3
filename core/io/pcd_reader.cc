#include "core/io/pcd_reader.h"

#include <pcl/common/io.h>
#include <pcl/io/lzf.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "core/common/error.h"

namespace ism {
namespace {

// Bounds that no real cloud comes near; they keep a hostile header's arithmetic and allocations
// small before the body has been looked at.
constexpr size_t kMaxHeaderBytes = 1 << 20;
constexpr uint64_t kMaxPointBytes = 1 << 20;
constexpr uint64_t kMaxPoints = std::numeric_limits<int32_t>::max();  // pixel indices are int
// LZF encodes at most 264 repeated bytes in a 3-byte back reference: a body can unpack to no more
// than 88 times its size.
constexpr uint64_t kMaxLzfRatio = 88;

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw Error(ErrorCode::kInvalidInput, source + ": malformed PCD file: " + what);
}

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

// Into `words` (cleared first), so that an ASCII body's lines reuse one buffer.
void splitWords(std::string_view line, std::vector<std::string_view>& words) {
  words.clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && isBlank(line[i])) ++i;
    const size_t start = i;
    while (i < line.size() && !isBlank(line[i])) ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
}

template <class T>
bool parseWhole(std::string_view word, T& value) {
  if (!word.empty() && word[0] == '+') word.remove_prefix(1);  // from_chars takes '-' only
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  return error == std::errc() && end == word.data() + word.size();
}

std::string quoted(std::string_view word) {
  constexpr size_t kShown = 40;
  return "'" + std::string(word.substr(0, kShown)) + (word.size() > kShown ? "...'" : "'");
}

uint8_t datatypeOf(char type, uint64_t size) {
  using F = pcl::PCLPointField;
  switch (type) {
    case 'F': return size == 4 ? F::FLOAT32 : size == 8 ? F::FLOAT64 : 0;
    case 'I': return size == 1 ? F::INT8 : size == 2 ? F::INT16 : size == 4 ? F::INT32 : size == 8 ? F::INT64 : 0;
    case 'U': return size == 1 ? F::UINT8 : size == 2 ? F::UINT16 : size == 4 ? F::UINT32 : size == 8 ? F::UINT64 : 0;
    default: return 0;
  }
}

struct Header {
  std::vector<std::string_view> names, sizes, types, counts;
  bool has_width = false, has_height = false, has_points = false;
  uint64_t width = 0, height = 1, points = 0;
  std::string_view data;  // ascii, binary or binary_compressed
  size_t body_start = 0;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};  // tx ty tz qw qx qy qz
};

uint64_t headerCount(const std::vector<std::string_view>& words, const char* keyword, const std::string& source) {
  uint64_t value = 0;
  if (words.size() != 2 || !parseWhole(words[1], value) || value > std::numeric_limits<uint32_t>::max()) {
    fail(source, std::string(keyword) + " must be one whole number below 2^32, the header has " +
                     quoted(words.size() > 1 ? words[1] : std::string_view()));
  }
  return value;
}

Header readHeader(std::string_view bytes, const std::string& source) {
  Header header;
  size_t pos = 0;
  for (int line_number = 1;; ++line_number) {
    if (pos >= bytes.size()) fail(source, "the header has no DATA line");
    if (pos > kMaxHeaderBytes) fail(source, "no DATA line in the first 1 MiB");
    size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) end = bytes.size();
    std::vector<std::string_view> words;
    splitWords(bytes.substr(pos, end - pos), words);
    pos = end + 1;
    if (words.empty() || words[0][0] == '#') continue;
    const std::string_view keyword = words[0];
    const std::vector<std::string_view> values(words.begin() + 1, words.end());
    if (keyword == "VERSION") {
      continue;
    } else if (keyword == "FIELDS" || keyword == "COLUMNS") {
      header.names = values;
    } else if (keyword == "SIZE") {
      header.sizes = values;
    } else if (keyword == "TYPE") {
      header.types = values;
    } else if (keyword == "COUNT") {
      header.counts = values;
    } else if (keyword == "WIDTH") {
      header.width = headerCount(words, "WIDTH", source);
      header.has_width = true;
    } else if (keyword == "HEIGHT") {
      header.height = headerCount(words, "HEIGHT", source);
      header.has_height = true;
    } else if (keyword == "POINTS") {
      header.points = headerCount(words, "POINTS", source);
      header.has_points = true;
    } else if (keyword == "VIEWPOINT") {
      bool ok = values.size() == 7;
      for (size_t i = 0; ok && i < 7; ++i) ok = parseWhole(values[i], header.viewpoint[i]) && std::isfinite(header.viewpoint[i]);
      if (!ok) fail(source, "VIEWPOINT must be 7 finite numbers (tx ty tz qw qx qy qz)");
    } else if (keyword == "DATA") {
      if (values.size() != 1) fail(source, "DATA must name one of ascii, binary, binary_compressed");
      header.data = values[0];
      header.body_start = std::min(pos, bytes.size());
      return header;
    } else {
      fail(source, "header line " + std::to_string(line_number) + " starts with " + quoted(keyword) +
                       ", not a PCD keyword");
    }
  }
}

struct Layout {
  pcl::PCLPointCloud2 blob;     // fields, width, height, point_step; data still empty
  uint64_t values_per_point = 0;
  uint64_t stored_point_bytes = 0;  // without the "_" padding fields that compressed bodies omit
};

Layout layoutOf(const Header& header, const std::string& source) {
  const size_t n = header.names.size();
  if (n == 0) fail(source, "the header has no FIELDS line");
  const auto sameLength = [&](const std::vector<std::string_view>& list, const char* keyword, bool required) {
    if (list.empty() && !required) return;
    if (list.size() != n) {
      fail(source, std::string(keyword) + " has " + std::to_string(list.size()) + " entries for " +
                       std::to_string(n) + " FIELDS");
    }
  };
  sameLength(header.sizes, "SIZE", true);
  sameLength(header.types, "TYPE", true);
  sameLength(header.counts, "COUNT", false);
  Layout layout;
  auto& blob = layout.blob;
  uint64_t offset = 0;
  for (size_t i = 0; i < n; ++i) {
    const std::string name(header.names[i]);
    uint64_t size = 0, count = 1;
    const bool size_ok = parseWhole(header.sizes[i], size);
    const uint8_t datatype = header.types[i].size() == 1 && size_ok ? datatypeOf(header.types[i][0], size) : 0;
    if (datatype == 0) {
      fail(source, "field '" + name + "' has TYPE " + quoted(header.types[i]) + " and SIZE " + quoted(header.sizes[i]) +
                       ", not a PCD type (I or U of 1, 2, 4, 8 bytes; F of 4 or 8)");
    }
    if (!header.counts.empty() && (!parseWhole(header.counts[i], count) || count == 0 || count > kMaxPointBytes)) {
      fail(source, "field '" + name + "' has COUNT " + quoted(header.counts[i]) + ", expected 1 to 2^20");
    }
    pcl::PCLPointField field;
    field.name = name;
    field.offset = static_cast<uint32_t>(offset);
    field.datatype = datatype;
    field.count = static_cast<uint32_t>(count);
    blob.fields.push_back(field);
    offset += size * count;
    if (offset > kMaxPointBytes) fail(source, "its points are larger than 1 MiB each");
    layout.values_per_point += count;
    if (name != "_") layout.stored_point_bytes += size * count;
  }
  blob.point_step = static_cast<uint32_t>(offset);

  // v0.5 files have POINTS only (an unorganized cloud), v0.7 has all three, which must agree.
  uint64_t points = header.points;
  if (header.has_width) {
    const uint64_t grid = header.width * header.height;  // both below 2^32
    if (header.has_points && grid != header.points) {
      fail(source, "WIDTH x HEIGHT = " + std::to_string(header.width) + " x " + std::to_string(header.height) +
                       " does not match POINTS " + std::to_string(header.points));
    }
    points = grid;
    blob.width = static_cast<uint32_t>(header.width);
    blob.height = static_cast<uint32_t>(header.height);
  } else if (header.has_points) {
    if (header.has_height && header.height != 1) fail(source, "HEIGHT without WIDTH");
    blob.width = static_cast<uint32_t>(points);
    blob.height = 1;
  } else {
    fail(source, "the header has neither WIDTH nor POINTS");
  }
  if (points == 0) fail(source, "the header declares no points");
  if (points > kMaxPoints) fail(source, std::to_string(points) + " points are more than 2^31 - 1");
  blob.row_step = blob.point_step * blob.width;
  return layout;
}

void readBinary(std::string_view body, pcl::PCLPointCloud2& blob, const std::string& source) {
  const uint64_t points = static_cast<uint64_t>(blob.width) * blob.height;
  const uint64_t needed = points * blob.point_step;
  if (body.size() < needed) {
    fail(source, "the binary body holds " + std::to_string(body.size()) + " bytes, the header's " +
                     std::to_string(points) + " points of " + std::to_string(blob.point_step) + " bytes need " +
                     std::to_string(needed));
  }
  blob.data.assign(body.begin(), body.begin() + static_cast<std::ptrdiff_t>(needed));
}

// PCL writes a compressed body as its compressed and uncompressed sizes (uint32, little-endian)
// and then LZF data that unpacks to each field's values for all points, field after field,
// without the "_" padding fields.
void readCompressed(std::string_view body, const Layout& layout, pcl::PCLPointCloud2& blob, const std::string& source) {
  uint32_t sizes[2];  // compressed, uncompressed
  if (body.size() < sizeof sizes) fail(source, "the binary_compressed body is truncated before its sizes");
  std::memcpy(sizes, body.data(), sizeof sizes);
  body.remove_prefix(sizeof sizes);
  const uint64_t points = static_cast<uint64_t>(blob.width) * blob.height;
  const uint64_t needed = points * layout.stored_point_bytes;
  if (sizes[1] != needed) {
    fail(source, "the compressed body unpacks to " + std::to_string(sizes[1]) + " bytes, the header's points need " +
                     std::to_string(needed));
  }
  if (sizes[0] > body.size()) {
    fail(source, "the compressed body is " + std::to_string(sizes[0]) + " bytes long but the file holds " +
                     std::to_string(body.size()) + " after the header (truncated)");
  }
  if (needed > kMaxLzfRatio * sizes[0]) {
    fail(source, "a compressed body of " + std::to_string(sizes[0]) + " bytes cannot unpack to " +
                     std::to_string(needed));
  }
  std::vector<uint8_t> packed(needed);
  if (needed > 0 && pcl::lzfDecompress(body.data(), sizes[0], packed.data(), sizes[1]) != sizes[1]) {
    fail(source, "the compressed body is corrupt (LZF data does not unpack to " + std::to_string(needed) + " bytes)");
  }
  blob.data.assign(points * blob.point_step, 0);
  const uint8_t* block = packed.data();
  for (const auto& field : blob.fields) {
    if (field.name == "_") continue;
    const size_t bytes = static_cast<size_t>(pcl::getFieldSize(field.datatype)) * field.count;
    for (uint64_t i = 0; i < points; ++i) std::memcpy(&blob.data[i * blob.point_step + field.offset], block + i * bytes, bytes);
    block += bytes * points;
  }
}

// One ASCII value into its field's binary slot. Colour is a packed 32-bit field that PCL writes
// as an unsigned integer even when its TYPE is F; other writers put the float whose bits it is.
bool storeAscii(std::string_view word, const pcl::PCLPointField& field, uint8_t* at) {
  using F = pcl::PCLPointField;
  const auto integer = [&](auto min, auto max) {
    using T = decltype(min);
    std::conditional_t<std::is_signed_v<T>, int64_t, uint64_t> value;
    if (!parseWhole(word, value) || value < min || value > max) return false;
    const T narrow = static_cast<T>(value);
    std::memcpy(at, &narrow, sizeof narrow);
    return true;
  };
  switch (field.datatype) {
    case F::INT8: return integer(int8_t{INT8_MIN}, int8_t{INT8_MAX});
    case F::INT16: return integer(int16_t{INT16_MIN}, int16_t{INT16_MAX});
    case F::INT32: return integer(int32_t{INT32_MIN}, int32_t{INT32_MAX});
    case F::INT64: return integer(int64_t{INT64_MIN}, int64_t{INT64_MAX});
    case F::UINT8: return integer(uint8_t{0}, uint8_t{UINT8_MAX});
    case F::UINT16: return integer(uint16_t{0}, uint16_t{UINT16_MAX});
    case F::UINT32: return integer(uint32_t{0}, uint32_t{UINT32_MAX});
    case F::UINT64: return integer(uint64_t{0}, uint64_t{UINT64_MAX});
    case F::FLOAT32: {
      if ((field.name == "rgb" || field.name == "rgba") && word.find_first_not_of("0123456789") == std::string_view::npos) {
        return integer(uint32_t{0}, uint32_t{UINT32_MAX});
      }
      double value;
      if (!parseWhole(word, value)) return false;
      const float narrow = static_cast<float>(value);
      std::memcpy(at, &narrow, sizeof narrow);
      return true;
    }
    case F::FLOAT64: {
      double value;
      if (!parseWhole(word, value)) return false;
      std::memcpy(at, &value, sizeof value);
      return true;
    }
    default: return false;
  }
}

void readAscii(std::string_view body, const Layout& layout, pcl::PCLPointCloud2& blob, const std::string& source) {
  const uint64_t points = static_cast<uint64_t>(blob.width) * blob.height;
  // Every value takes a character and a separator: a short body is refused before allocating.
  if (points * layout.values_per_point > body.size() / 2 + 1) {
    fail(source, "the ascii body of " + std::to_string(body.size()) + " bytes is too short for the header's " +
                     std::to_string(points) + " points of " + std::to_string(layout.values_per_point) + " values");
  }
  blob.data.assign(points * blob.point_step, 0);
  std::vector<std::string_view> words;
  size_t pos = 0;
  for (uint64_t i = 0; i < points;) {
    if (pos >= body.size()) {
      fail(source, "the ascii body ends after " + std::to_string(i) + " of " + std::to_string(points) + " points");
    }
    size_t end = body.find('\n', pos);
    if (end == std::string_view::npos) end = body.size();
    splitWords(body.substr(pos, end - pos), words);
    pos = end + 1;
    if (words.empty()) continue;
    if (words.size() != layout.values_per_point) {
      fail(source, "point " + std::to_string(i + 1) + " has " + std::to_string(words.size()) +
                       " values, the header's fields need " + std::to_string(layout.values_per_point));
    }
    uint8_t* point = &blob.data[i * blob.point_step];
    size_t w = 0;
    for (const auto& field : blob.fields) {
      const size_t size = static_cast<size_t>(pcl::getFieldSize(field.datatype));
      for (uint32_t c = 0; c < field.count; ++c, ++w) {
        if (!storeAscii(words[w], field, point + field.offset + c * size)) {
          fail(source, "point " + std::to_string(i + 1) + ": " + quoted(words[w]) + " is not a valid value for field '" +
                           field.name + "'");
        }
      }
    }
    ++i;
  }
}

}  // namespace

PcdCloud parsePcd(std::string_view bytes, const std::string& source) {
  const Header header = readHeader(bytes, source);
  Layout layout = layoutOf(header, source);
  PcdCloud cloud;
  cloud.blob = std::move(layout.blob);
  const std::string_view body = bytes.substr(header.body_start);
  if (header.data == "binary") {
    readBinary(body, cloud.blob, source);
  } else if (header.data == "binary_compressed") {
    readCompressed(body, layout, cloud.blob, source);
  } else if (header.data == "ascii") {
    readAscii(body, layout, cloud.blob, source);
  } else {
    fail(source, "DATA " + quoted(header.data) + " is not ascii, binary or binary_compressed");
  }
  const double* v = header.viewpoint;
  cloud.origin = Eigen::Vector4f(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]), 0.0f);
  cloud.orientation = Eigen::Quaternionf(static_cast<float>(v[3]), static_cast<float>(v[4]), static_cast<float>(v[5]),
                                         static_cast<float>(v[6]));
  // Normalising a zero quaternion would give NaN rotations downstream.
  if (!(cloud.orientation.norm() > 1e-6f)) fail(source, "the VIEWPOINT quaternion (qw qx qy qz) is zero");
  return cloud;
}

}  // namespace ism
