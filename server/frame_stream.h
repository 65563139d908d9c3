#pragma once
// One StreamFrames call. Frames are read as they come, queued, and recognised one at a time
// on the worker pool; results are written in frame order, one write in flight at a time.
//   EVERY_FRAME: the queue holds at most kMaxQueuedFrames; when full, reading pauses and
//     gRPC flow control slows the sender.
//   LATEST_FRAME_WINS: reading never pauses; a newer frame replaces the waiting ones, whose
//     ids ride along with the next result.
// A frame that fails (bad input) gets a FrameResult carrying the error; the stream goes on. A
// message that is not a StreamFramesRequest at all (its frame id is unknown), or settings that
// cannot be served, end the stream: the frames read before it are answered first, and the final
// status names the frames read but not processed. Every frame read thus gets a result, an error
// result, or its id in the final status.
// Messages travel as bytes, decoded and encoded here (see decodeMessage).
#include <grpcpp/support/server_callback.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "ism/v1/service.grpc.pb.h"
#include "server/auth.h"
#include "server/service_context.h"

namespace ism::server {

class FrameStream;

// The open streams. A shutdown must end them itself: gRPC's drain waits for every call, and a
// client streaming from a sensor never ends its own.
class OpenStreams {
 public:
  bool add(FrameStream* stream);  // false once shutDown() ran: the stream must end at once
  void remove(FrameStream* stream);
  // Every open stream stops reading, answers the frames it already took and ends UNAVAILABLE.
  void shutDown();
  size_t size() const;

 private:
  // Recursive: a stream that ends inside shutDown() may leave the set from the same thread.
  mutable std::recursive_mutex mutex_;
  std::set<FrameStream*> streams_;
  bool shutting_down_ = false;
};

class FrameStream final : public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  static constexpr size_t kMaxQueuedFrames = 4;
  static constexpr size_t kMaxPendingResults = 4;

  // `slot` (may be null) is the client's stream slot, given back when the stream is done.
  // `open` lists the stream until OnDone.
  FrameStream(const ServiceContext& service, grpc::CallbackServerContext* context, std::unique_ptr<StreamSlot> slot,
              OpenStreams& open);

  // The server is stopping: read no more frames, answer the queued ones, end UNAVAILABLE so that
  // the client sends the rest again (elsewhere, or after the restart).
  void shutDown();

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 private:
  struct Settings {
    v1::BackpressurePolicy policy = v1::BACKPRESSURE_POLICY_EVERY_FRAME;
    v1::RecognitionOptions options;
  };
  struct Frame {
    v1::StreamFramesRequest request;
    std::shared_ptr<const Settings> settings;
    std::chrono::steady_clock::time_point received;
  };

  // gRPC operations to start once the lock is released, so that a reaction running on
  // another thread never waits for us. Finish goes last: `this` may be deleted right after.
  struct Actions {
    bool read = false;
    const grpc::ByteBuffer* write = nullptr;
    bool finish = false;
  };
  void act(const Actions& actions);

  void processNext();  // on the worker pool
  // nullopt when the server gave the frame up at shutdown.
  std::optional<v1::FrameResult> process(const Frame& frame, const std::vector<uint64_t>& skipped);
  // The *Locked helpers expect mutex_ held and add what is to be started to `actions`.
  void resumeReadingLocked(Actions* actions);
  void scheduleLocked();
  void finishIfDoneLocked(Actions* actions);
  std::string notProcessedLocked() const;  // "; not processed: frames 7, 8", or ""

  const ServiceContext& service_;
  grpc::CallbackServerContext* context_;
  OpenStreams& open_;
  std::unique_ptr<StreamSlot> slot_;
  const std::string stream_id_;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::atomic<bool> cancelled_{false};
  ShouldStop should_stop_;

  std::mutex mutex_;
  grpc::ByteBuffer read_buffer_;
  size_t messages_read_ = 0;
  std::shared_ptr<const Settings> settings_ = std::make_shared<Settings>();
  std::deque<Frame> queued_;
  std::vector<uint64_t> skipped_;
  std::deque<grpc::ByteBuffer> results_;  // encoded FrameResults
  bool reading_ = false;
  bool reads_done_ = false;
  bool processing_ = false;
  bool writing_ = false;
  bool finished_ = false;
  bool shutting_down_ = false;
  grpc::Status ending_;  // a message that ends the stream once the frames before it are answered
  bool broken_ = false;  // a result could not be written: the client is no longer receiving
  std::vector<uint64_t> not_processed_;  // frames read but never to be processed
  grpc::Status final_status_;
  size_t frames_ = 0;
};

}  // namespace ism::server
