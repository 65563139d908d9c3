#include "server/frame_stream.h"

#include <spdlog/spdlog.h>

#include "core/common/error.h"
#include "server/status_mapping.h"
#include "server/untrusted_text.h"

namespace ism::server {

bool OpenStreams::add(FrameStream* stream) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  streams_.insert(stream);
  return !shutting_down_;
}

void OpenStreams::remove(FrameStream* stream) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  streams_.erase(stream);
}

size_t OpenStreams::size() const {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  return streams_.size();
}

void OpenStreams::shutDown() {
  // Held throughout: a stream cannot finish its OnDone (and be deleted) on another thread while
  // it is being told. A copy, because one that ends right here leaves the set meanwhile.
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  shutting_down_ = true;
  const std::set<FrameStream*> streams = streams_;
  for (FrameStream* stream : streams) stream->shutDown();
}

FrameStream::FrameStream(const ServiceContext& service, grpc::CallbackServerContext* context,
                         std::unique_ptr<StreamSlot> slot, OpenStreams& open)
    : service_(service),
      context_(context),
      open_(open),
      slot_(std::move(slot)),
      stream_id_(requestId("")),
      should_stop_(service.stopper(context, &cancelled_)) {
  service_.metrics.streamOpened();
  spdlog::info("[{}] stream opened by {}", stream_id_, loggable(context_->peer()));
  reading_ = true;
  StartRead(&read_buffer_);
  if (!open_.add(this)) shutDown();  // opened while the server is stopping
}

void FrameStream::shutDown() {
  Actions actions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    shutting_down_ = true;
    finishIfDoneLocked(&actions);
  }
  act(actions);
}

void FrameStream::act(const Actions& actions) {
  if (actions.read) StartRead(&read_buffer_);
  if (actions.write != nullptr) StartWrite(actions.write);
  if (actions.finish) {
    // Given back before the status leaves: a client that saw its stream end may open the
    // next one at once and must find the slot free.
    slot_.reset();
    Finish(final_status_);
  }
}

void FrameStream::OnReadDone(bool ok) {
  // Decoded before taking the lock: only this reaction touches the read buffer, and a big frame
  // must not hold up the workers' bookkeeping.
  v1::StreamFramesRequest request;
  grpc::Status undecodable;
  if (ok) {
    try {
      decodeMessage(read_buffer_, "message " + std::to_string(++messages_read_) + " of the stream", &request);
    } catch (const Error& e) {
      undecodable = grpc::Status(toStatusCode(e.code()), e.what());
    }
    read_buffer_.Clear();
  }
  Actions actions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    reading_ = false;
    if (!ok) {
      reads_done_ = true;  // the client half-closed (or the call broke: OnCancel says which)
    } else if (shutting_down_) {
      // Not taken: the stream ends UNAVAILABLE naming this frame, so its client knows to send it
      // again.
      if (undecodable.ok() && request.has_scene()) not_processed_.push_back(request.frame_id());
    } else if (!undecodable.ok()) {
      ending_ = undecodable;
    } else {
      if (request.has_settings()) {
        auto settings = std::make_shared<Settings>();
        settings->options = request.settings().options();
        switch (request.settings().policy()) {
          case v1::BACKPRESSURE_POLICY_UNSPECIFIED:
          case v1::BACKPRESSURE_POLICY_EVERY_FRAME:
            break;
          case v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS:
            settings->policy = v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS;
            break;
          default:
            ending_ = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                   "settings.policy " + std::to_string(request.settings().policy()) + " (frame " +
                                       std::to_string(request.frame_id()) + ") is not supported");
            if (request.has_scene()) not_processed_.push_back(request.frame_id());
        }
        settings_ = std::move(settings);
      }
      if (ending_.ok() && request.has_scene()) {
        if (settings_->policy == v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS && !queued_.empty()) {
          for (const auto& frame : queued_) skipped_.push_back(frame.request.frame_id());
          service_.metrics.framesSkipped(queued_.size());
          queued_.clear();
        }
        queued_.push_back({std::move(request), settings_, std::chrono::steady_clock::now()});
        ++frames_;
      }
      scheduleLocked();
      resumeReadingLocked(&actions);
    }
    finishIfDoneLocked(&actions);
  }
  act(actions);
}

void FrameStream::resumeReadingLocked(Actions* actions) {
  const bool queue_full = settings_->policy != v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS &&
                          queued_.size() >= kMaxQueuedFrames;
  if (reading_ || reads_done_ || queue_full || cancelled_ || shutting_down_ || !ending_.ok()) return;
  reading_ = true;
  actions->read = true;
}

void FrameStream::scheduleLocked() {
  if (processing_ || queued_.empty() || results_.size() >= kMaxPendingResults || cancelled_ || broken_) {
    return;
  }
  processing_ = true;
  service_.pool.submit([this] { processNext(); });
}

void FrameStream::processNext() {
  Frame frame;
  std::vector<uint64_t> skipped;
  Actions actions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    frame = std::move(queued_.front());
    queued_.pop_front();
    skipped.swap(skipped_);  // frames dropped before this one was taken
    resumeReadingLocked(&actions);
  }
  act(actions);  // no finish possible: processing_ is still set

  std::optional<v1::FrameResult> processed = process(frame, skipped);
  grpc::ByteBuffer result;
  if (processed) encodeMessage(*processed, &result);

  actions = {};
  {
    std::lock_guard<std::mutex> lock(mutex_);
    processing_ = false;
    if (processed) {
      results_.push_back(std::move(result));
      if (!writing_) {
        writing_ = true;
        actions.write = &results_.front();
      }
    } else {
      not_processed_.push_back(frame.request.frame_id());
      not_processed_.insert(not_processed_.end(), skipped.begin(), skipped.end());
    }
    scheduleLocked();
    finishIfDoneLocked(&actions);
  }
  act(actions);
}

std::optional<v1::FrameResult> FrameStream::process(const Frame& frame, const std::vector<uint64_t>& skipped) {
  const auto start = std::chrono::steady_clock::now();
  v1::FrameResult out;
  out.set_frame_id(frame.request.frame_id());
  out.set_timestamp_us(frame.request.timestamp_us());
  out.set_queued_ms(std::chrono::duration<double, std::milli>(start - frame.received).count());
  for (uint64_t id : skipped) out.add_skipped_frame_ids(id);
  grpc::Status status;
  try {
    // Held while it is recognised; a frame that does not fit fails alone, as bad input does.
    std::unique_ptr<Admission::Ticket> ticket;
    if (grpc::Status refused = service_.admission.admit(frame.request.ByteSizeLong(), "this frame", &ticket);
        !refused.ok()) {
      throw Error(ErrorCode::kResourceExhausted, refused.error_message());
    }
    service_.recognize(stream_id_ + "/" + std::to_string(frame.request.frame_id()), frame.request.scene(),
                       frame.settings->options, should_stop_, out.mutable_result());
  } catch (...) {
    status = service_.whyStopped(context_, statusFromCurrentException());
    // Given up at shutdown: no error result, the final status names the frame to send again.
    if (service_.workAbandoned()) return std::nullopt;
    out.mutable_error()->set_code(status.error_code());
    out.mutable_error()->set_message(status.error_message());
    spdlog::warn("[{}/{}] frame failed: {}: {}", stream_id_, frame.request.frame_id(),
                 statusCodeName(status.error_code()), loggable(status.error_message(), kMaxStatusMessage));
  }
  service_.metrics.recordRequest(
      "StreamFrames.frame", status.error_code(),
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return out;
}

void FrameStream::OnWriteDone(bool ok) {
  Actions actions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    writing_ = false;
    results_.pop_front();
    if (!ok) {
      broken_ = true;  // nothing more reaches the client
    } else if (!results_.empty()) {
      writing_ = true;
      actions.write = &results_.front();
    }
    scheduleLocked();
    finishIfDoneLocked(&actions);
  }
  act(actions);
}

void FrameStream::OnCancel() {
  cancelled_ = true;
  Actions actions;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finishIfDoneLocked(&actions);
  }
  act(actions);
}

void FrameStream::finishIfDoneLocked(Actions* actions) {
  // A shutdown does not wait for the client's next frame: the pending read ends with the call.
  if (finished_ || processing_ || writing_ || (reading_ && !shutting_down_)) return;
  // Frames already read are answered before the stream ends, also when a bad message ends it;
  // only a client that is gone (cancelled, or no longer receiving) cuts them short.
  const bool gone = cancelled_ || broken_;
  const bool drained = queued_.empty() && results_.empty();
  if (!gone && !(drained && (reads_done_ || shutting_down_ || !ending_.ok()))) return;
  finished_ = true;
  if (broken_) {
    final_status_ = {grpc::StatusCode::CANCELLED, "the client stopped receiving results"};
  } else if (cancelled_) {
    final_status_ = service_.whyStopped(context_, {grpc::StatusCode::CANCELLED, "the client cancelled the stream"});
  } else if (!ending_.ok()) {
    final_status_ = {ending_.error_code(), ending_.error_message() + "; every frame read before it was answered" +
                                               notProcessedLocked()};
  } else if (!reads_done_) {
    final_status_ = {grpc::StatusCode::UNAVAILABLE,
                     "the server is shutting down: frames of this stream without a result were not processed" +
                         notProcessedLocked() + "; send them again (to another server, or after the restart)"};
  }
  actions->finish = true;
}

std::string FrameStream::notProcessedLocked() const {
  if (not_processed_.empty()) return "";
  constexpr size_t kMaxNamed = 32;  // keeps the status message short whatever the client sent
  std::string ids;
  for (size_t i = 0; i < std::min(not_processed_.size(), kMaxNamed); ++i) {
    ids += (ids.empty() ? "" : ", ") + std::to_string(not_processed_[i]);
  }
  if (not_processed_.size() > kMaxNamed) ids += " and " + std::to_string(not_processed_.size() - kMaxNamed) + " more";
  return "; not processed: frame" + std::string(not_processed_.size() > 1 ? "s " : " ") + ids;
}

void FrameStream::OnDone() {
  open_.remove(this);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  service_.metrics.streamClosed();
  service_.metrics.recordRequest("StreamFrames", final_status_.error_code(), seconds);
  spdlog::info("[{}] stream closed: {} frames in {:.1f}s, {}{}", stream_id_, frames_, seconds,
               statusCodeName(final_status_.error_code()),
               final_status_.ok() ? "" : ": " + loggable(final_status_.error_message(), kMaxStatusMessage));
  delete this;
}

}  // namespace ism::server
