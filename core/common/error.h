#pragma once
// One error type for all of core. The code says what kind of failure it is so that the
// service can map it to a gRPC status in one place (server/status_mapping.cc); the message
// names the thing that is wrong (file, field, value) so a user can act on it.
#include <stdexcept>
#include <string>

namespace ism {

enum class ErrorCode {
  kInvalidInput,       // the caller's data is wrong (empty cloud, bad sizes, NaN-only...)
  kNotFound,           // a named file, model or category does not exist
  kIo,                 // a file exists but cannot be read or written
  kCorruptModel,       // a model file fails its version or integrity checks
  kResourceExhausted,  // input larger than a configured limit
  kCancelled,          // the caller gave up (ShouldStop returned true)
  kInternal,           // a bug: an invariant of ours does not hold
};

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

const char* errorCodeName(ErrorCode code);

}  // namespace ism
