#include "client/cli/stream.h"

#include <chrono>
#include <exception>
#include <iomanip>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "client/cli/output.h"
#include "ism/v1/service.grpc.pb.h"

namespace ism::client {
namespace {

using Call = grpc::ClientReaderWriter<v1::StreamFramesRequest, v1::FrameResult>;

constexpr auto kFirstReconnectDelay = std::chrono::milliseconds(250);
constexpr auto kMaxReconnectDelay = std::chrono::milliseconds(8000);

// A frame sent and not answered yet: sent again after a reconnection.
struct SentFrame {
  int64_t timestamp_us = 0;
  v1::Scene scene;
};

// What the writer thread and the reader share over all the calls of one run.
class StreamRun {
 public:
  StreamRun(const Connection& connection, FrameSource& source, const RecognitionFlags& flags,
            const StreamParams& params)
      : connection_(connection), source_(source), flags_(flags), params_(params) {}

  int run();

 private:
  // One StreamFrames call: frames out on a thread of its own, results in here.
  grpc::Status streamOnce(bool own_connection, bool* answered_any);
  // The writer: first the frames a broken call left unanswered, then new ones from the source.
  void writeFrames(Call& call);
  bool send(Call& call, v1::StreamFramesRequest& request, uint64_t id, const SentFrame& frame);
  void take(const v1::FrameResult& result);
  void print(const v1::FrameResult& result) const;
  // Whether to open another call after `status`; sets `status` to what the run ends with if not.
  bool reconnect(grpc::Status* status, bool answered_any, int* failures_in_a_row);
  int summary(const grpc::Status& status) const;
  // With mutex_ held: nothing more to take from the source.
  bool exhausted() const { return source_done_ || (params_.max_frames > 0 && taken_ >= params_.max_frames); }
  double elapsedSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

  const Connection& connection_;
  FrameSource& source_;
  const RecognitionFlags& flags_;
  const StreamParams params_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();

  mutable std::mutex mutex_;
  std::map<uint64_t, SentFrame> unanswered_;  // by frame id
  uint64_t taken_ = 0;                        // frames taken from the source so far
  bool source_done_ = false;
  std::exception_ptr source_error_;
  // Only the reading thread touches these.
  uint64_t received_ = 0, skipped_ = 0, failed_ = 0, reconnections_ = 0;
};

int StreamRun::run() {
  std::cerr << "streaming " << source_.describe() << " ("
            << (params_.latest_wins ? "latest frame wins" : "every frame") << ")\n";
  grpc::Status status;
  for (int failures_in_a_row = 0;;) {
    bool answered_any = false;
    // A reconnection gets a channel of its own: the old one may still be backing off from the
    // server it lost, and would fail the new call at once.
    status = streamOnce(/*own_connection=*/reconnections_ > 0, &answered_any);
    if (!reconnect(&status, answered_any, &failures_in_a_row)) break;
    ++reconnections_;
  }
  return summary(status);
}

grpc::Status StreamRun::streamOnce(bool own_connection, bool* answered_any) {
  auto stub = v1::FurnitureRecognizer::NewStub(connection_.channel(own_connection));
  grpc::ClientContext context;
  connection_.prepare(&context);
  auto call = stub->StreamFrames(&context);
  std::thread writer([&] { writeFrames(*call); });
  for (v1::FrameResult result; call->Read(&result);) {
    take(result);
    *answered_any = true;
    print(result);
  }
  writer.join();
  return call->Finish();
}

void StreamRun::writeFrames(Call& call) {
  v1::StreamFramesRequest request;
  auto* settings = request.mutable_settings();
  settings->set_policy(params_.latest_wins ? v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS
                                           : v1::BACKPRESSURE_POLICY_EVERY_FRAME);
  *settings->mutable_options() = flags_.build();
  try {
    std::vector<std::pair<uint64_t, SentFrame>> again;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      again.assign(unanswered_.begin(), unanswered_.end());
    }
    bool open = true;
    for (const auto& [id, frame] : again) {
      if (!(open = send(call, request, id, frame))) break;  // the call is over; Finish says why
    }
    while (open) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (exhausted()) break;
      }
      auto next = source_.next();
      if (!next) {
        std::lock_guard<std::mutex> lock(mutex_);
        source_done_ = true;
        break;
      }
      SentFrame frame{next->timestamp_us, std::move(next->scene)};
      uint64_t id;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        id = ++taken_;
        unanswered_[id] = frame;
      }
      open = send(call, request, id, frame);
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    source_error_ = std::current_exception();
    source_done_ = true;
  }
  call.WritesDone();
}

// Never called with mutex_ held: Write waits for flow control, which waits for the reader.
bool StreamRun::send(Call& call, v1::StreamFramesRequest& request, uint64_t id, const SentFrame& frame) {
  request.set_frame_id(id);
  request.set_timestamp_us(frame.timestamp_us);
  *request.mutable_scene() = frame.scene;
  flags_.applyTo(request.mutable_scene());
  const bool ok = call.Write(request);
  request.clear_settings();  // the first message of each call carries them
  return ok;
}

void StreamRun::take(const v1::FrameResult& result) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    unanswered_.erase(result.frame_id());
    for (auto id : result.skipped_frame_ids()) unanswered_.erase(id);
  }
  ++received_;
  skipped_ += static_cast<uint64_t>(result.skipped_frame_ids_size());
  if (result.has_error()) ++failed_;
}

void StreamRun::print(const v1::FrameResult& result) const {
  if (connection_.json) {
    std::cout << toJson(result) << std::endl;  // a line per result as it comes, also into a pipe
    return;
  }
  std::cout << "frame " << result.frame_id() << ": ";
  if (result.has_error()) {
    std::cout << "error " << statusName(static_cast<grpc::StatusCode>(result.error().code())) << ": "
              << result.error().message();
  } else {
    std::cout << result.result().hypotheses_size() << " hypotheses";
    for (const auto& h : result.result().hypotheses()) {
      // The confidence rather than the score: it means the same for every category.
      std::cout << " [" << h.category() << " p=" << std::fixed << std::setprecision(2) << h.confidence() << " at ("
                << h.center().x() << ", " << h.center().y() << ", " << h.center().z() << ")]";
    }
    std::cout << std::fixed << std::setprecision(1) << ", " << result.result().total_ms() << " ms";
  }
  if (result.skipped_frame_ids_size() > 0) {
    std::cout << ", skipped";
    for (auto id : result.skipped_frame_ids()) std::cout << " " << id;
  }
  std::cout << std::fixed << std::setprecision(1) << " (" << received_ / elapsedSeconds() << " fps)" << std::endl;
}

bool StreamRun::reconnect(grpc::Status* status, bool answered_any, int* failures_in_a_row) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (status->error_code() != grpc::StatusCode::UNAVAILABLE || source_error_) return false;
  if (exhausted() && unanswered_.empty()) {
    *status = grpc::Status::OK;  // broke after the last answer: nothing is missing
    return false;
  }
  if (answered_any) *failures_in_a_row = 0;
  if (++*failures_in_a_row > params_.reconnect_attempts) {
    *status = grpc::Status(status->error_code(),
                           status->error_message() + " (gave up after " + std::to_string(params_.reconnect_attempts) +
                               " reconnection attempts; " + std::to_string(unanswered_.size()) +
                               " frames sent were not answered)");
    return false;
  }
  const auto delay = std::min<std::chrono::milliseconds>(
      kFirstReconnectDelay * (1 << std::min(*failures_in_a_row - 1, 10)), kMaxReconnectDelay);
  std::cerr << "stream broke: " << statusName(status->error_code()) << ": " << status->error_message() << "; "
            << unanswered_.size() << " frames unanswered; reconnecting in " << std::fixed << std::setprecision(2)
            << std::chrono::duration<double>(delay).count() << " s (attempt " << *failures_in_a_row << " of "
            << params_.reconnect_attempts << ")\n";
  lock.unlock();
  std::this_thread::sleep_for(delay);
  return true;
}

int StreamRun::summary(const grpc::Status& status) const {
  const double elapsed = elapsedSeconds();
  std::lock_guard<std::mutex> lock(mutex_);
  std::cerr << taken_ << " frames sent, " << received_ << " results (" << failed_ << " failed), " << skipped_
            << " skipped, " << reconnections_ << " reconnections, " << std::fixed << std::setprecision(2)
            << received_ / elapsed << " results/s over " << elapsed << " s\n";
  if (!status.ok()) {
    std::cerr << "error: stream: " << statusName(status.error_code()) << ": " << status.error_message() << "\n";
    return kStatusBase + status.error_code();
  }
  if (source_error_) {
    try {
      std::rethrow_exception(source_error_);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
    }
    return kLocalFailure;
  }
  return 0;
}

}  // namespace

int runStream(const Connection& connection, FrameSource& source, const RecognitionFlags& flags,
              const StreamParams& params) {
  return StreamRun(connection, source, flags, params).run();
}

}  // namespace ism::client
