#pragma once
// The model file: a ModelFile envelope (magic, format version, CRC-32 of the payload) around a
// serialized ModelData message, both in proto/ism/v1/model.proto so that any language can read
// a model's metadata. Loading checks magic, version and CRC and throws
// Error(kCorruptModel / kNotFound / kIo) with a message naming the file and the problem.
#include <string>

#include "core/model/model.h"
#include "ism/v1/model.pb.h"

namespace ism {

constexpr uint32_t kModelFormatVersion = 1;

void saveModel(const Model& model, const std::string& path);
Model loadModel(const std::string& path);
std::string serializeModel(const Model& model);
// Whether the two models' front ends are the same as their files write them: features extracted
// for one serve the other (an ensemble's models share one front end, ensemble.h).
bool sameFrontEnd(const Model& a, const Model& b);
Model parseModel(const std::string& bytes, const std::string& source);

// A model file with what it says about itself, for listings that show what the file holds.
struct ModelFileContents {
  Model model;
  uint32_t format_version = 0;
  std::string version;  // CRC-32 of the whole file, 8 hex digits: changes whenever the file does
  // The file's ModelData without the codebooks' centres and the vote tables (their sizes are
  // the model's): front end, thresholds, boxes and provenance exactly as written.
  v1::ModelData description;
};
ModelFileContents parseModelFile(const std::string& bytes, const std::string& source);
// parseModelFile of the file at `path`, which must be a regular file of at most `max_bytes`:
// anything else (a directory, a FIFO, a device such as /dev/zero) is refused before a byte is
// read, with one message whether or not the path exists, and so is a larger file.
ModelFileContents readModelFile(const std::string& path, size_t max_bytes);

}  // namespace ism
