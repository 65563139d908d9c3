#pragma once
// A decompression bomb: a 1x1 16-bit grey PNG whose image data inflates to `inflated_mb` MB of
// zeros (about 1 KB on the wire per MB). Built from one deflated MB repeated: after a full
// flush deflate refers to nothing before, so the same bytes are valid anywhere in the stream,
// and the Adler-32 is combined rather than computed over the whole.
#include <arpa/inet.h>
#include <zlib.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace ism::testing {

inline std::string pngChunkOf(const std::string& type, const std::string& data) {
  std::string out;
  const uint32_t length = htonl(static_cast<uint32_t>(data.size()));
  out.append(reinterpret_cast<const char*>(&length), 4);
  out += type + data;
  uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(type.data()), 4);
  crc = crc32(crc, reinterpret_cast<const Bytef*>(data.data()), static_cast<uInt>(data.size()));
  const uint32_t big = htonl(static_cast<uint32_t>(crc));
  out.append(reinterpret_cast<const char*>(&big), 4);
  return out;
}

inline std::string depthPngBomb(int inflated_mb) {
  const std::vector<unsigned char> zeros(1 << 20, 0);
  z_stream zs{};
  if (deflateInit(&zs, 9) != Z_OK) throw std::runtime_error("deflateInit failed");
  std::string flushed(64 * 1024, '\0'), finished(64, '\0');
  zs.next_in = const_cast<Bytef*>(zeros.data());
  zs.avail_in = static_cast<uInt>(zeros.size());
  zs.next_out = reinterpret_cast<Bytef*>(flushed.data());
  zs.avail_out = static_cast<uInt>(flushed.size());
  deflate(&zs, Z_FULL_FLUSH);
  flushed.resize(flushed.size() - zs.avail_out);
  zs.next_out = reinterpret_cast<Bytef*>(finished.data());
  zs.avail_out = static_cast<uInt>(finished.size());
  deflate(&zs, Z_FINISH);  // the final (empty) block and the Adler-32 of one MB
  finished.resize(finished.size() - zs.avail_out - 4);
  deflateEnd(&zs);

  const std::string header = flushed.substr(0, 2), one_mb = flushed.substr(2);
  std::string stream = header;
  const uLong adler_mb = adler32(adler32(0L, nullptr, 0), zeros.data(), static_cast<uInt>(zeros.size()));
  uLong adler = adler32(0L, nullptr, 0);
  for (int i = 0; i < inflated_mb; ++i) {
    stream += one_mb;
    adler = adler32_combine(adler, adler_mb, static_cast<z_off_t>(zeros.size()));
  }
  stream += finished;
  const uint32_t big_adler = htonl(static_cast<uint32_t>(adler));
  stream.append(reinterpret_cast<const char*>(&big_adler), 4);

  std::string ihdr(13, '\0');
  const uint32_t one = htonl(1);
  std::memcpy(ihdr.data(), &one, 4);
  std::memcpy(ihdr.data() + 4, &one, 4);
  ihdr[8] = 16;  // bit depth; colour type 0 (grey), no interlacing
  return std::string("\x89PNG\r\n\x1a\n", 8) + pngChunkOf("IHDR", ihdr) + pngChunkOf("IDAT", stream) +
         pngChunkOf("IEND", "");
}

}  // namespace ism::testing
