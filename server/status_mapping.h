#pragma once
// The one place where failures become gRPC statuses: ism::Error codes map to status codes,
// anything else unexpected becomes INTERNAL carrying its message (never a crash).
#include <grpcpp/support/status.h>

#include <exception>
#include <string>

#include "core/common/error.h"

namespace ism::server {

grpc::StatusCode toStatusCode(ErrorCode code);

// "NOT_FOUND", "DEADLINE_EXCEEDED"...: for logs and metric labels.
std::string statusCodeName(grpc::StatusCode code);

// Call inside a catch block: converts the exception in flight. The message is capped
// (untrusted_text.h): it may quote what a client sent.
grpc::Status statusFromCurrentException();

}  // namespace ism::server
