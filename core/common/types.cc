#include "core/common/types.h"

#include "core/common/error.h"

namespace ism {

void throwIfStopped(const ShouldStop& should_stop, const char* where) {
  if (should_stop && should_stop()) {
    throw Error(ErrorCode::kCancelled, std::string("stopped during ") + where);
  }
}

}  // namespace ism
