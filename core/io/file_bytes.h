#pragma once
// Whole files as bytes: what the decoders (PCD, PLY, depth PNG, model files) and the service's
// TLS and token files read, and what the encoders write.
#include <string>

namespace ism {

// Throws Error(kNotFound) when `path` does not exist, Error(kIo) when it is a directory or
// cannot be read; the message names the file.
std::string readFileBytes(const std::string& path);

// Creates or truncates `path`. Throws Error(kIo) naming the file when it cannot be written.
void writeFileBytes(const std::string& path, const std::string& bytes);

}  // namespace ism
