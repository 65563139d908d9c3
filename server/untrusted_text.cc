#include "server/untrusted_text.h"

#include <algorithm>
#include <cstdio>

namespace ism::server {

std::string loggable(std::string_view text, size_t max_bytes) {
  std::string out;
  const size_t kept = std::min(text.size(), max_bytes);
  out.reserve(kept + 32);
  for (size_t i = 0; i < kept; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char escaped[5];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", c);
      out += escaped;
    }
  }
  if (kept < text.size()) out += "...(" + std::to_string(text.size()) + " bytes)";
  return out;
}

std::string capped(std::string text, size_t max_bytes) {
  if (text.size() <= max_bytes) return text;
  const size_t size = text.size();
  // Cut before a UTF-8 continuation byte, so that a client decoding the message as UTF-8 is
  // not handed half a character.
  size_t cut = max_bytes;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xc0) == 0x80) --cut;
  text.resize(cut);
  return text + "...(" + std::to_string(size) + " bytes in all)";
}

}  // namespace ism::server
