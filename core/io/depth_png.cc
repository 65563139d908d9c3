#include "core/io/depth_png.h"

#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <cstring>

#include "core/common/error.h"

namespace ism {
namespace {

// A depth frame larger than this on either side is not a sensor image; refusing it early keeps
// a forged header from making libpng allocate gigabytes.
constexpr png_uint_32 kMaxSide = 16384;

// libpng reports errors by longjmp. Nothing with a destructor may be skipped by the jump, so
// every libpng call that can fail sits in a small guarded function below that touches only
// this plain struct; the C++ callers turn a `false` into an ism::Error.
struct PngContext {
  const char* data = nullptr;  // decode: input bytes
  size_t size = 0;
  size_t offset = 0;
  const ShouldStop* should_stop = nullptr;  // decode: asked after every row
  bool stopped = false;
  std::string* out = nullptr;  // encode: output buffer
  char message[256] = {};
};

void onPngError(png_structp png, png_const_charp message) {
  auto* context = static_cast<PngContext*>(png_get_error_ptr(png));
  std::snprintf(context->message, sizeof(context->message), "%s", message);
  png_longjmp(png, 1);
}

void onPngWarning(png_structp, png_const_charp) {}  // benign (unknown chunks...); errors still abort

void readFromMemory(png_structp png, png_bytep dest, png_size_t length) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (context->size - context->offset < length) png_error(png, "data is truncated");
  std::memcpy(dest, context->data + context->offset, length);
  context->offset += length;
}

void writeToString(png_structp png, png_bytep src, png_size_t length) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  bool appended = true;
  try {
    context->out->append(reinterpret_cast<const char*>(src), length);
  } catch (const std::bad_alloc&) {
    appended = false;  // the exception must be gone before libpng longjmps out of this frame
  }
  if (!appended) png_error(png, "out of memory while encoding");
}

void flushNothing(png_structp) {}

void afterRow(png_structp png, png_uint_32, int) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (context->should_stop == nullptr || !*context->should_stop) return;
  bool stop = true;
  try {
    stop = (*context->should_stop)();
  } catch (...) {
    // an exception must not cross libpng's C frames; asking failed, so stop
  }
  if (stop) {
    context->stopped = true;
    png_error(png, "stopped");
  }
}

uint32_t bigEndian32(const std::string& bytes, size_t at) {
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data()) + at;
  return uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | uint32_t(b[3]);
}

// What the image data of a 16-bit grey image inflates to: each row with its filter byte, and
// rows of each of the seven passes when interlaced (PNG spec, 8.2: Adam7).
uint64_t inflatedSize(uint64_t width, uint64_t height, bool interlaced) {
  const auto rows = [](uint64_t w, uint64_t h) { return w == 0 || h == 0 ? 0 : h * (1 + 2 * w); };
  if (!interlaced) return rows(width, height);
  static const int kStart[7][2] = {{0, 0}, {4, 0}, {0, 4}, {2, 0}, {0, 2}, {1, 0}, {0, 1}};  // x, y
  static const int kStep[7][2] = {{8, 8}, {8, 8}, {4, 8}, {4, 4}, {2, 4}, {2, 2}, {1, 2}};
  uint64_t total = 0;
  for (int pass = 0; pass < 7; ++pass) {
    const auto count = [](uint64_t size, int start, int step) {
      return size > static_cast<uint64_t>(start) ? (size - start + step - 1) / step : 0;
    };
    total += rows(count(width, kStart[pass][0], kStep[pass][0]), count(height, kStart[pass][1], kStep[pass][1]));
  }
  return total;
}

// libpng inflates a PNG's image data to its very end, however far past the rows it goes (to
// check the stream): a 1x1 image whose data inflates to gigabytes keeps it busy for a minute.
// Inflating once here into a scratch buffer, and stopping one byte past what the header's size
// holds, bounds that work by the header. Malformed or damaged chunks and zlib errors are left
// for libpng to report.
void checkInflatedSize(const std::string& bytes, const std::string& source, const ShouldStop& should_stop) {
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) throw Error(ErrorCode::kInternal, "zlib could not allocate its state");
  struct End {
    z_stream* zs;
    ~End() { inflateEnd(zs); }
  } end{&zs};
  uint64_t limit = 0, inflated = 0;
  uint32_t width = 0, height = 0;
  std::vector<unsigned char> scratch(64 * 1024);
  uint64_t since_asked = 0;
  for (size_t at = 8; at + 12 <= bytes.size();) {
    const uint64_t length = bigEndian32(bytes, at);
    const std::string type = bytes.substr(at + 4, 4);
    if (length > bytes.size() - at - 12) return;
    const size_t data = at + 8;
    at = data + length + 4;
    if (type == "IHDR" && length >= 13) {
      width = bigEndian32(bytes, data);
      height = bigEndian32(bytes, data + 4);
      limit = inflatedSize(width, height, bytes[data + 12] != 0);
    } else if (type == "IDAT") {
      // A damaged chunk is libpng's to report (as a CRC error), not to be judged by what it inflates to.
      const uLong crc = crc32(crc32(0L, reinterpret_cast<const Bytef*>(bytes.data() + data - 4), 4),
                              reinterpret_cast<const Bytef*>(bytes.data() + data), static_cast<uInt>(length));
      if (crc != bigEndian32(bytes, data + length)) return;
      zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data() + data));
      zs.avail_in = static_cast<uInt>(length);
      while (zs.avail_in > 0) {
        zs.next_out = scratch.data();
        zs.avail_out = static_cast<uInt>(scratch.size());
        const int result = inflate(&zs, Z_NO_FLUSH);
        inflated += scratch.size() - zs.avail_out;
        if (inflated > limit) {
          throw Error(ErrorCode::kInvalidInput,
                      source + ": the PNG's image data inflates to more than the " + std::to_string(limit) +
                          " bytes a " + std::to_string(width) + "x" + std::to_string(height) +
                          " 16-bit image holds (" + std::to_string(bytes.size()) + " bytes compressed)");
        }
        if (result == Z_BUF_ERROR) break;  // this chunk's bytes are used up mid-stream: the next IDAT goes on
        if (result != Z_OK) return;         // the end of the stream, or an error libpng will name
        if ((since_asked += scratch.size()) >= (4u << 20)) {
          since_asked = 0;
          throwIfStopped(should_stop, "PNG decoding");
        }
      }
    } else if (type == "IEND") {
      return;
    }
  }
}

bool hostIsLittleEndian() {
  const uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

bool guardedReadHeader(png_structp png, png_infop info) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_user_limits(png, kMaxSide, kMaxSide);
  png_read_info(png, info);
  return true;
}

bool guardedReadRows(png_structp png, png_infop info, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  // PNG stores 16-bit samples big-endian.
  if (hostIsLittleEndian()) png_set_swap(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_read_image(png, rows);
  png_read_end(png, nullptr);  // checks the trailing CRCs, so a damaged file does not pass
  return true;
}

bool guardedWrite(png_structp png, png_infop info, png_uint_32 width, png_uint_32 height, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_IHDR(png, info, width, height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (hostIsLittleEndian()) png_set_swap(png);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

std::string describeFormat(int color_type, int bit_depth) {
  const char* kind = "unknown colour type";
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY: kind = "greyscale"; break;
    case PNG_COLOR_TYPE_GRAY_ALPHA: kind = "greyscale+alpha"; break;
    case PNG_COLOR_TYPE_RGB: kind = "RGB"; break;
    case PNG_COLOR_TYPE_RGB_ALPHA: kind = "RGBA"; break;
    case PNG_COLOR_TYPE_PALETTE: kind = "palette"; break;
  }
  return std::to_string(bit_depth) + "-bit " + kind;
}

// Owns libpng's read or write structs; destroying them is the only cleanup libpng needs.
class PngHandle {
 public:
  PngHandle(bool reading, PngContext* context) : reading_(reading) {
    png_ = reading ? png_create_read_struct(PNG_LIBPNG_VER_STRING, context, onPngError, onPngWarning)
                   : png_create_write_struct(PNG_LIBPNG_VER_STRING, context, onPngError, onPngWarning);
    if (png_ != nullptr) info_ = png_create_info_struct(png_);
    if (png_ == nullptr || info_ == nullptr) throw Error(ErrorCode::kInternal, "libpng could not allocate its state");
  }
  ~PngHandle() {
    if (reading_) {
      png_destroy_read_struct(&png_, &info_, nullptr);
    } else {
      png_destroy_write_struct(&png_, &info_);
    }
  }
  PngHandle(const PngHandle&) = delete;
  PngHandle& operator=(const PngHandle&) = delete;
  png_structp png() const { return png_; }
  png_infop info() const { return info_; }

 private:
  bool reading_;
  png_structp png_ = nullptr;
  png_infop info_ = nullptr;
};

std::vector<png_bytep> rowPointers(const uint16_t* pixels, int width, int height) {
  std::vector<png_bytep> rows(static_cast<size_t>(height));
  for (int r = 0; r < height; ++r) {
    // libpng's row type is non-const even for writing; it does not modify them.
    rows[r] = reinterpret_cast<png_bytep>(const_cast<uint16_t*>(pixels + static_cast<size_t>(r) * width));
  }
  return rows;
}

}  // namespace

DepthPng decodeDepthPng16(const std::string& bytes, const std::string& source, const ShouldStop& should_stop) {
  constexpr size_t kSignatureSize = 8;
  if (bytes.size() < kSignatureSize ||
      png_sig_cmp(reinterpret_cast<png_const_bytep>(bytes.data()), 0, kSignatureSize) != 0) {
    throw Error(ErrorCode::kInvalidInput, source + ": not a PNG (" + std::to_string(bytes.size()) +
                                              " bytes without the PNG signature)");
  }
  PngContext context;
  context.data = bytes.data();
  context.size = bytes.size();
  context.should_stop = &should_stop;
  PngHandle handle(/*reading=*/true, &context);
  png_set_read_fn(handle.png(), &context, readFromMemory);
  png_set_read_status_fn(handle.png(), afterRow);
  // Ancillary chunks (text, ICC profiles) carry nothing a depth image needs, and some of them
  // are compressed: they are skipped rather than inflated.
  png_set_keep_unknown_chunks(handle.png(), PNG_HANDLE_CHUNK_NEVER, nullptr, -1);
  if (!guardedReadHeader(handle.png(), handle.info())) {
    throw Error(ErrorCode::kInvalidInput, source + ": broken PNG header: " + context.message);
  }
  const int color_type = png_get_color_type(handle.png(), handle.info());
  const int bit_depth = png_get_bit_depth(handle.png(), handle.info());
  if (color_type != PNG_COLOR_TYPE_GRAY || bit_depth != 16) {
    throw Error(ErrorCode::kInvalidInput, source + ": PNG is " + describeFormat(color_type, bit_depth) +
                                              ", expected a 16-bit single-channel depth image");
  }
  DepthPng image;
  image.width = static_cast<int>(png_get_image_width(handle.png(), handle.info()));
  image.height = static_cast<int>(png_get_image_height(handle.png(), handle.info()));
  checkInflatedSize(bytes, source, should_stop);
  image.pixels.resize(static_cast<size_t>(image.width) * image.height);
  auto rows = rowPointers(image.pixels.data(), image.width, image.height);
  if (!guardedReadRows(handle.png(), handle.info(), rows.data())) {
    if (context.stopped) throw Error(ErrorCode::kCancelled, "stopped during PNG decoding");
    throw Error(ErrorCode::kInvalidInput, source + ": broken PNG data: " + context.message);
  }
  return image;
}

std::string encodeDepthPng16(const DepthPng& image) {
  if (image.width <= 0 || image.height <= 0 || static_cast<png_uint_32>(image.width) > kMaxSide ||
      static_cast<png_uint_32>(image.height) > kMaxSide) {
    throw Error(ErrorCode::kInvalidInput, "depth PNG size " + std::to_string(image.width) + "x" +
                                              std::to_string(image.height) + " is outside 1.." +
                                              std::to_string(kMaxSide));
  }
  if (image.pixels.size() != static_cast<size_t>(image.width) * image.height) {
    throw Error(ErrorCode::kInvalidInput, "depth PNG has " + std::to_string(image.pixels.size()) +
                                              " pixels, expected width*height = " +
                                              std::to_string(static_cast<size_t>(image.width) * image.height));
  }
  std::string out;
  PngContext context;
  context.out = &out;
  PngHandle handle(/*reading=*/false, &context);
  png_set_write_fn(handle.png(), &context, writeToString, flushNothing);
  auto rows = rowPointers(image.pixels.data(), image.width, image.height);
  if (!guardedWrite(handle.png(), handle.info(), static_cast<png_uint_32>(image.width),
                    static_cast<png_uint_32>(image.height), rows.data())) {
    throw Error(ErrorCode::kInternal, std::string("PNG encoding failed: ") + context.message);
  }
  return out;
}

}  // namespace ism
