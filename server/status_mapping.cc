#include "server/status_mapping.h"

#include <absl/status/status.h>

#include <new>

#include "server/untrusted_text.h"

namespace ism::server {

grpc::StatusCode toStatusCode(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidInput:
      return grpc::StatusCode::INVALID_ARGUMENT;
    case ErrorCode::kNotFound:
      return grpc::StatusCode::NOT_FOUND;
    case ErrorCode::kResourceExhausted:
      return grpc::StatusCode::RESOURCE_EXHAUSTED;
    case ErrorCode::kCancelled:
      return grpc::StatusCode::CANCELLED;
    // A model file that cannot be read or is corrupt is the server's state, not the caller's
    // mistake: the call may succeed once an operator fixes the file.
    case ErrorCode::kIo:
    case ErrorCode::kCorruptModel:
      return grpc::StatusCode::FAILED_PRECONDITION;
    case ErrorCode::kInternal:
      return grpc::StatusCode::INTERNAL;
  }
  return grpc::StatusCode::INTERNAL;
}

std::string statusCodeName(grpc::StatusCode code) {
  // grpc::StatusCode and absl::StatusCode share their numbering by design.
  return absl::StatusCodeToString(static_cast<absl::StatusCode>(code));
}

grpc::Status statusFromCurrentException() {
  try {
    throw;
  } catch (const Error& e) {
    return {toStatusCode(e.code()), capped(e.what())};
  } catch (const std::bad_alloc&) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "out of memory while processing the request"};
  } catch (const std::exception& e) {
    return {grpc::StatusCode::INTERNAL, capped(std::string("internal error: ") + e.what())};
  } catch (...) {
    return {grpc::StatusCode::INTERNAL, "internal error: unknown exception"};
  }
}

}  // namespace ism::server
