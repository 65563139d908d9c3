#pragma once
// Text a client sent (request ids, model names, paths, and error messages that quote them) made
// safe for a log line and for a status message: a newline or an escape sequence in a request id
// must not forge a log line of its own, and a megabyte of it must not become a megabyte of log
// or exceed gRPC's metadata limit on the way back.
#include <cstddef>
#include <string>
#include <string_view>

namespace ism::server {

// Control characters, backslashes and bytes outside ASCII as \xNN; cut after `max_bytes` of the
// input, saying how long it was.
std::string loggable(std::string_view text, size_t max_bytes = 160);

// Status messages are cut to this, saying how long they were.
constexpr size_t kMaxStatusMessage = 1024;
std::string capped(std::string text, size_t max_bytes = kMaxStatusMessage);

}  // namespace ism::server
