#pragma once
// `ism-client stream`: frames from a source on a StreamFrames call, one printed result per frame.
#include <cstdint>
#include <memory>

#include "client/cli/common.h"
#include "client/cli/frame_source.h"

namespace ism::client {

struct StreamParams {
  bool latest_wins = true;     // LATEST_FRAME_WINS, else EVERY_FRAME
  uint64_t max_frames = 0;     // 0: the whole source
  int reconnect_attempts = 6;  // failures in a row before giving up
};

// Streams `source`. When the call ends UNAVAILABLE (server restarted, crashed, or shut down for
// an update) it opens a new one after a growing delay, sends again the frames that had no result
// and goes on with the source. Returns the process exit code.
int runStream(const Connection& connection, FrameSource& source, const RecognitionFlags& flags,
              const StreamParams& params);

}  // namespace ism::client
