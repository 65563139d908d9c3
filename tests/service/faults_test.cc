// Faults around the real ism-server: SIGTERM under load, model administration under load, a
// corrupt model file, and a streaming ism-client that outlives a server restart. Every call
// must get its answer or UNAVAILABLE (never another failure, never a silent loss, never a hang).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <atomic>
#include <filesystem>
#include <future>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <thread>

#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "proto/wire/messages.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;
using v1::FurnitureRecognizer;
using Clock = std::chrono::steady_clock;

// A channel of its own per client thread, as separate robots would have.
std::shared_ptr<grpc::Channel> ownChannel(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

std::string codeName(grpc::StatusCode code) {
  static const std::map<grpc::StatusCode, std::string> names{
      {grpc::StatusCode::OK, "OK"},
      {grpc::StatusCode::CANCELLED, "CANCELLED"},
      {grpc::StatusCode::INVALID_ARGUMENT, "INVALID_ARGUMENT"},
      {grpc::StatusCode::DEADLINE_EXCEEDED, "DEADLINE_EXCEEDED"},
      {grpc::StatusCode::NOT_FOUND, "NOT_FOUND"},
      {grpc::StatusCode::RESOURCE_EXHAUSTED, "RESOURCE_EXHAUSTED"},
      {grpc::StatusCode::FAILED_PRECONDITION, "FAILED_PRECONDITION"},
      {grpc::StatusCode::INTERNAL, "INTERNAL"},
      {grpc::StatusCode::UNAVAILABLE, "UNAVAILABLE"}};
  const auto it = names.find(code);
  return it != names.end() ? it->second : std::to_string(static_cast<int>(code));
}

std::string describe(const std::map<grpc::StatusCode, int>& counts) {
  std::string out;
  for (const auto& [code, n] : counts) out += (out.empty() ? "" : ", ") + codeName(code) + " " + std::to_string(n);
  return out;
}

// SIGTERM while many Recognize calls run and a stream sends frames as fast as it may: every
// call started gets its answer or UNAVAILABLE, every frame sent is answered or the stream ends
// with UNAVAILABLE (so its client knows to send it again), and the process exits 0.
TEST(Faults, SigtermUnderLoadAnswersOrRefusesEveryCall) {
  ServerProcess server({"--drain-seconds", "30"});
  v1::RecognizeRequest request;
  *request.mutable_scene() = rawDepthMessage(smallScene().depth);
  const v1::Scene frame_scene = pngDepthMessage(smallScene(1).depth);

  std::mutex mutex;
  std::map<grpc::StatusCode, int> counts;
  std::vector<std::string> others;
  std::atomic<int> answered{0}, answered_after_signal{0}, clients_answered{0};
  std::atomic<bool> signalled{false};
  constexpr int kClients = 8;
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&] {
      auto stub = FurnitureRecognizer::NewStub(ownChannel(server.address()));
      // Closed loop until the server is gone: the first UNAVAILABLE ends this client.
      for (bool first = true;; first = false) {
        grpc::ClientContext context;
        context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(90));
        // gRPC 1.51's first connection attempt sometimes fails at once; the first call, made
        // while the server surely runs, waits for the connection instead of failing.
        context.set_wait_for_ready(first);
        v1::RecognizeResponse response;
        const grpc::Status status = stub->Recognize(&context, request, &response);
        std::lock_guard<std::mutex> lock(mutex);
        ++counts[status.error_code()];
        if (status.ok()) {
          ++answered;
          if (first) ++clients_answered;
          if (signalled) ++answered_after_signal;
          continue;
        }
        if (status.error_code() != grpc::StatusCode::UNAVAILABLE) {
          others.push_back(codeName(status.error_code()) + ": " + status.error_message());
        }
        return;
      }
    });
  }

  // The stream: one writer as fast as flow control lets it, one reader.
  grpc::Status stream_status;
  std::set<uint64_t> frames_sent, frames_answered;
  std::atomic<bool> stream_answered{false};
  std::thread streamer([&] {
    auto stub = FurnitureRecognizer::NewStub(ownChannel(server.address()));
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(90));
    context.set_wait_for_ready(true);  // started while the server surely runs (see above)
    auto stream = stub->StreamFrames(&context);
    std::mutex frames_mutex;
    std::thread writer([&] {
      for (uint64_t id = 1;; ++id) {
        v1::StreamFramesRequest frame;
        frame.set_frame_id(id);
        *frame.mutable_scene() = frame_scene;
        {
          std::lock_guard<std::mutex> lock(frames_mutex);
          frames_sent.insert(id);
        }
        if (!stream->Write(frame)) {
          std::lock_guard<std::mutex> lock(frames_mutex);
          frames_sent.erase(id);  // never left: Write failing means the call is over
          break;
        }
      }
    });
    for (v1::FrameResult result; stream->Read(&result);) {
      EXPECT_TRUE(result.has_result()) << result.frame_id() << ": " << result.error().message();
      std::lock_guard<std::mutex> lock(frames_mutex);
      frames_answered.insert(result.frame_id());
      stream_answered = true;
    }
    writer.join();
    stream_status = stream->Finish();
  });

  // Signal once the load is under way: every client answered once, the stream too. A client whose
  // first call (which waits for the connection) were still connecting at the signal would wait
  // for a server that never comes back, until its deadline.
  const auto give_up = Clock::now() + std::chrono::seconds(60);
  while ((clients_answered < kClients || !stream_answered) && Clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(clients_answered, kClients) << "the load never got going";  // signalled anyway: the threads must end
  EXPECT_TRUE(stream_answered) << "the stream never got going";
  signalled = true;
  const auto signal_time = Clock::now();
  const int exit_code = server.terminate(std::chrono::seconds(60));
  const double exit_s = std::chrono::duration<double>(Clock::now() - signal_time).count();
  for (auto& c : clients) c.join();
  streamer.join();

  EXPECT_EQ(exit_code, 0);
  EXPECT_TRUE(others.empty()) << others.size() << " calls failed otherwise, first: " << others.front();
  int total = 0;
  for (const auto& [code, n] : counts) total += n;
  // Each client ends with exactly one UNAVAILABLE: none hung, none was lost.
  EXPECT_EQ(counts[grpc::StatusCode::UNAVAILABLE], kClients) << describe(counts);
  EXPECT_EQ(total, counts[grpc::StatusCode::OK] + counts[grpc::StatusCode::UNAVAILABLE]) << describe(counts);
  // The calls running at the signal were drained, not dropped.
  EXPECT_GT(answered_after_signal, 0);

  EXPECT_TRUE(stream_status.ok() || stream_status.error_code() == grpc::StatusCode::UNAVAILABLE)
      << codeName(stream_status.error_code()) << ": " << stream_status.error_message();
  EXPECT_FALSE(frames_answered.empty());
  if (stream_status.ok()) {
    EXPECT_EQ(frames_answered, frames_sent) << "an OK stream must have answered every frame it took";
  }
  for (uint64_t id : frames_answered) EXPECT_TRUE(frames_sent.count(id)) << id;
  std::cout << "SIGTERM under load: " << total << " Recognize calls (" << describe(counts) << ", "
            << answered_after_signal << " answered after the signal); stream: " << frames_sent.size()
            << " frames sent, " << frames_answered.size() << " answered, " << codeName(stream_status.error_code())
            << " " << stream_status.error_message() << "; exit " << exit_code << " after " << exit_s << " s\n";
}

// Clients that retry on UNAVAILABLE, as gRPC's retry policies do, keep calling through a SIGTERM
// until the process is gone: every call they make ends OK or UNAVAILABLE, never CANCELLED, also
// those still queued or running when the drain time is over and those that reach the server as
// it stops. Four rounds, since a call racing the end is a race.
TEST(Faults, CallsRacingTheShutdownAreRefusedUnavailable) {
  v1::RecognizeRequest request;
  *request.mutable_scene() = rawDepthMessage(smallScene(0, 640, 480).depth);
  std::map<grpc::StatusCode, int> counts;
  std::map<std::string, int> messages;
  std::vector<std::string> others;
  for (int round = 0; round < 4; ++round) {
    ServerProcess server({"--drain-seconds", "0.5"});
    std::mutex mutex;
    std::atomic<int> clients_answered{0};
    std::atomic<bool> gone{false};
    std::vector<std::thread> clients;
    for (int c = 0; c < 8; ++c) {
      clients.emplace_back([&] {
        auto stub = FurnitureRecognizer::NewStub(ownChannel(server.address()));
        for (bool first = true; !gone; first = false) {
          grpc::ClientContext context;
          context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(90));
          context.set_wait_for_ready(first);  // see SigtermUnderLoadAnswersOrRefusesEveryCall
          v1::RecognizeResponse response;
          const grpc::Status status = stub->Recognize(&context, request, &response);
          if (status.ok() && first) ++clients_answered;
          std::lock_guard<std::mutex> lock(mutex);
          ++counts[status.error_code()];
          if (!status.ok() && status.error_code() != grpc::StatusCode::UNAVAILABLE) {
            others.push_back(codeName(status.error_code()) + ": " + status.error_message());
          }
          if (!status.ok()) ++messages[status.error_message().substr(0, 48)];
          if (status.error_code() == grpc::StatusCode::UNAVAILABLE) {
            std::this_thread::sleep_for(std::chrono::milliseconds(1));  // a retry policy's backoff
          }
        }
      });
    }
    // Every client's first call, the one that waits for the connection, must be answered before
    // the signal: one still connecting then would wait for a server that never comes back, until
    // its deadline (as in SigtermUnderLoadAnswersOrRefusesEveryCall).
    const auto give_up = Clock::now() + std::chrono::seconds(60);
    while (clients_answered < 8 && Clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    EXPECT_EQ(clients_answered, 8) << "round " << round << ": the load never got going";
    EXPECT_EQ(server.terminate(std::chrono::seconds(60)), 0);
    gone = true;
    for (auto& c : clients) c.join();
  }
  EXPECT_TRUE(others.empty()) << others.size() << " calls failed otherwise, first: " << others.front();
  EXPECT_GT(counts[grpc::StatusCode::OK], 0);
  EXPECT_GT(counts[grpc::StatusCode::UNAVAILABLE], 0);
  // gRPC's own shutdown, which says nothing about the server going away, never ends a call: the
  // server answers what it took itself.
  EXPECT_EQ(messages.count("Cancelling all calls"), 0u);
  std::cout << "calls racing four shutdowns: " << describe(counts) << "; messages:\n";
  for (const auto& [message, n] : messages) std::cout << "  " << n << " x " << message << "\n";
}

// --drain-seconds 1 and a call whose work takes far longer: the sample scene's depth tiled 3 x 4
// (3.7 Mpixels, under --max-pixels) with every codeword of the shipped model voting: 7 s on 2
// cores here, 1.1 s for the untiled frame, which a faster machine could finish inside the drain
// (a machine under load only takes longer). Once the drain time is over
// the server stops the work, answers the call UNAVAILABLE saying why, and exits 0.
TEST(Faults, PastTheDrainTimeTheRunningWorkIsStoppedAndAnswered) {
  ServerProcess server({"--models", ISM_SOURCE_DIR "/models/default", "--drain-seconds", "1"});
  auto stub = FurnitureRecognizer::NewStub(server.channel());
  v1::ModelInfo model;
  {
    grpc::ClientContext context;
    ASSERT_TRUE(stub->GetModel(&context, {}, &model).ok());
  }
  const std::string sample_path = ISM_SOURCE_DIR "/models/sample/living_room_depth.png";
  const DepthPng sample = decodeDepthPng16(readFileBytes(sample_path), sample_path);
  DepthPng tiled;
  tiled.width = 3 * sample.width;
  tiled.height = 4 * sample.height;
  tiled.pixels.resize(static_cast<size_t>(tiled.width) * static_cast<size_t>(tiled.height));
  for (int v = 0; v < tiled.height; ++v) {
    for (int u = 0; u < tiled.width; ++u) {
      tiled.pixels[static_cast<size_t>(v) * tiled.width + u] =
          sample.pixels[static_cast<size_t>(v % sample.height) * sample.width + u % sample.width];
    }
  }
  v1::RecognizeRequest request;
  auto* depth = request.mutable_scene()->mutable_depth();
  depth->set_encoding(v1::DEPTH_ENCODING_PNG);
  depth->set_data(encodeDepthPng16(tiled));
  *depth->mutable_intrinsics() = wire::intrinsicsToProto(DepthIntrinsics{});  // the virtual Kinect's
  request.mutable_options()->mutable_strategy()->set_k(static_cast<int32_t>(model.global_codebook_size()));
  // The GetModel call stays open until gRPC is done with it, a moment after its answer arrived:
  // only once it is closed does one open call mean that the Recognize call has been taken.
  const auto waitForOpenCalls = [&](const std::string& line) {
    for (int attempt = 0; attempt < 600 && server.metrics().find(line) == std::string::npos; ++attempt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_NE(server.metrics().find(line), std::string::npos) << "no '" << line << "' in the metrics";
  };
  waitForOpenCalls("ism_open_calls 0");
  auto running = std::async(std::launch::async, [&] {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(300));
    v1::RecognizeResponse response;
    return stub->Recognize(&context, request, &response);
  });
  waitForOpenCalls("ism_open_calls 1");
  const auto signalled = Clock::now();
  EXPECT_EQ(server.terminate(std::chrono::seconds(120)), 0);
  const grpc::Status status = running.get();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
  EXPECT_NE(status.error_message().find("the server shut down before this call finished"), std::string::npos)
      << status.error_message();
  std::cout << "exited " << std::chrono::duration<double>(Clock::now() - signalled).count()
            << " s after SIGTERM with a 1 s drain; the call: " << status.error_message() << "\n";
}

// UnloadModel racing ReloadModels, ten times: whichever comes first, a model unloaded is not
// listed afterwards, although its file is still in the model directory.
TEST(Faults, AnUnloadRacingAReloadStaysUnloaded) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ism_unload_race_" + std::to_string(getpid()));
  fs::create_directories(dir);
  for (const std::string name : {"default", "extra"}) {
    fs::copy_file(tinyModelDirectory() + "/default.ismm", dir / (name + ".ismm"), fs::copy_options::overwrite_existing);
  }
  ServerProcess server({"--models", dir.string()});
  auto admin = FurnitureRecognizer::NewStub(server.channel());
  const auto listed = [&] {
    grpc::ClientContext context;
    v1::ListModelsResponse models;
    EXPECT_TRUE(admin->ListModels(&context, {}, &models).ok());
    std::set<std::string> names;
    for (const auto& m : models.models()) names.insert(m.name());
    return names;
  };
  for (int trial = 0; trial < 10; ++trial) {
    ASSERT_EQ(listed().count("extra"), 1u) << "trial " << trial;
    auto reload = std::async(std::launch::async, [&] {
      grpc::ClientContext context;
      v1::ReloadModelsResponse response;
      return FurnitureRecognizer::NewStub(server.channel())->ReloadModels(&context, {}, &response);
    });
    grpc::ClientContext context;
    v1::UnloadModelRequest unload;
    unload.set_name("extra");
    v1::UnloadModelResponse unloaded;
    const grpc::Status status = admin->UnloadModel(&context, unload, &unloaded);
    ASSERT_TRUE(reload.get().ok());
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(listed().count("extra"), 0u) << "trial " << trial << ": unloaded, yet listed after the reload";
    // A reload alone does not bring it back either; LoadModel does.
    grpc::ClientContext again;
    v1::ReloadModelsResponse reloaded;
    ASSERT_TRUE(admin->ReloadModels(&again, {}, &reloaded).ok());
    EXPECT_EQ(listed().count("extra"), 0u) << "trial " << trial;
    grpc::ClientContext load_context;
    v1::LoadModelRequest load;
    load.set_name("extra");
    load.set_path((dir / "extra.ismm").string());
    v1::ModelInfo info;
    ASSERT_TRUE(admin->LoadModel(&load_context, load, &info).ok());
  }
  fs::remove_all(dir);
}

// A closed loop of Recognize calls on the model that stays while an administrator reloads every
// model and loads and unloads another one, again and again: not one call may fail.
TEST(Faults, ModelReloadAndUnloadUnderLoadFailNoRequest) {
  ServerProcess server;
  const std::string model_file = tinyModelDirectory() + "/default.ismm";
  v1::RecognizeRequest request;
  *request.mutable_scene() = rawDepthMessage(smallScene().depth);

  std::atomic<bool> done{false};
  std::atomic<int> answered{0};
  std::mutex mutex;
  std::map<grpc::StatusCode, int> counts;
  std::vector<std::string> failures;
  std::vector<std::thread> clients;
  for (int c = 0; c < 4; ++c) {
    clients.emplace_back([&, c] {
      const auto channel = ownChannel(server.address());
      // Connected first (see SigtermUnderLoadAnswersOrRefusesEveryCall): the server surely runs.
      EXPECT_TRUE(channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::minutes(1)));
      auto stub = FurnitureRecognizer::NewStub(channel);
      v1::RecognizeRequest mine = request;
      // Half name the model, half rely on "the only one, or the one called default": a
      // second model coming and going must not change which one answers.
      if (c % 2 == 0) mine.mutable_options()->set_model("default");
      while (!done) {
        grpc::ClientContext context;
        context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
        v1::RecognizeResponse response;
        const grpc::Status status = stub->Recognize(&context, mine, &response);
        std::lock_guard<std::mutex> lock(mutex);
        ++counts[status.error_code()];
        if (!status.ok()) {
          failures.push_back(codeName(status.error_code()) + ": " + status.error_message());
        } else {
          ++answered;
          EXPECT_EQ(response.result().model_name(), "default");
        }
      }
    });
  }

  auto admin = FurnitureRecognizer::NewStub(ownChannel(server.address()));
  std::vector<std::string> admin_failures;
  auto call = [&](const std::string& what, const grpc::Status& status) {
    if (!status.ok())
      admin_failures.push_back(what + ": " + codeName(status.error_code()) + ": " + status.error_message());
  };
  int rounds = 0;
  const auto give_up = Clock::now() + std::chrono::seconds(40);
  // At least 10 rounds, and until 40 calls were answered, so that the changes overlap the load.
  while ((rounds < 10 || answered < 40) && Clock::now() < give_up) {
    ++rounds;
    {
      grpc::ClientContext context;
      v1::ReloadModelsResponse reloaded;
      call("reload", admin->ReloadModels(&context, {}, &reloaded));
      for (const auto& f : reloaded.failures()) admin_failures.push_back("reload of " + f.name() + ": " + f.message());
    }
    {
      grpc::ClientContext context;
      v1::LoadModelRequest load;
      load.set_name("other");
      load.set_path(model_file);
      v1::ModelInfo info;
      call("load", admin->LoadModel(&context, load, &info));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    {
      grpc::ClientContext context;
      v1::UnloadModelRequest unload;
      unload.set_name("other");
      v1::UnloadModelResponse unloaded;
      call("unload", admin->UnloadModel(&context, unload, &unloaded));
    }
  }
  done = true;
  for (auto& c : clients) c.join();
  std::cout << rounds << " rounds of reload + load + unload during " << describe(counts) << " Recognize calls\n";
  EXPECT_TRUE(admin_failures.empty()) << admin_failures.front();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
  EXPECT_GE(answered, 40);
}

// A model file replaced by a truncated copy, by garbage or with one byte damaged: ReloadModels
// and LoadModel refuse it naming the file and the check that failed, and the version loaded
// before keeps answering.
TEST(Faults, ACorruptModelFileIsRefusedAndTheOldModelServes) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ism_faults_models_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string file = fs::absolute(dir / "default.ismm").string();
  const std::string good = readFileBytes(tinyModelDirectory() + "/default.ismm");
  writeFileBytes(file, good);
  ServerProcess server({"--models", dir.string()});
  auto stub = FurnitureRecognizer::NewStub(server.channel());
  v1::RecognizeRequest request;
  *request.mutable_scene() = rawDepthMessage(smallScene().depth);

  auto version = [&] {
    grpc::ClientContext context;
    v1::GetModelRequest get;
    get.set_name("default");
    v1::ModelInfo info;
    EXPECT_TRUE(stub->GetModel(&context, get, &info).ok());
    return info.version();
  };
  const std::string loaded = version();
  ASSERT_FALSE(loaded.empty());

  std::string damaged = good;
  damaged[damaged.size() / 2] ^= 0x40;
  const std::vector<std::pair<std::string, std::string>> corruptions{
      {good.substr(0, good.size() / 2), "not a model file or truncated (the ModelFile envelope does not parse)"},
      {good.substr(0, good.size() - 1), "not a model file or truncated (the ModelFile envelope does not parse)"},
      {std::string("\x00\x01garbage, not a model", 23),
       "not a model file or truncated (the ModelFile envelope does not parse)"},
      {damaged, "CRC-32 mismatch (the file is truncated or damaged)"},
      {std::string(), "wrong magic: not a model file (they start with 'ISM-MODEL')"},
  };
  for (const auto& [bytes, reason] : corruptions) {
    SCOPED_TRACE(reason + ", " + std::to_string(bytes.size()) + " bytes");
    writeFileBytes(file, bytes);
    {
      grpc::ClientContext context;
      v1::ReloadModelsResponse reloaded;
      const grpc::Status status = stub->ReloadModels(&context, {}, &reloaded);
      ASSERT_TRUE(status.ok()) << status.error_message();
      ASSERT_EQ(reloaded.failures_size(), 1);
      EXPECT_EQ(reloaded.failures(0).name(), "default");
      EXPECT_EQ(reloaded.failures(0).path(), file);
      EXPECT_EQ(reloaded.failures(0).message(), file + ": " + reason) << reloaded.failures(0).message();
      ASSERT_EQ(reloaded.models_size(), 1);
      EXPECT_EQ(reloaded.models(0).version(), loaded);
    }
    {
      grpc::ClientContext context;
      v1::LoadModelRequest load;
      load.set_name("default");
      load.set_path(file);
      v1::ModelInfo info;
      const grpc::Status status = stub->LoadModel(&context, load, &info);
      EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
      EXPECT_EQ(status.error_message(), file + ": " + reason);
    }
    grpc::ClientContext context;
    v1::RecognizeResponse response;
    const grpc::Status status = stub->Recognize(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(response.result().model_version(), loaded);
    EXPECT_EQ(version(), loaded);
  }

  // Repaired, it loads again: the same bytes, the same version.
  writeFileBytes(file, good);
  grpc::ClientContext context;
  v1::ReloadModelsResponse reloaded;
  ASSERT_TRUE(stub->ReloadModels(&context, {}, &reloaded).ok());
  EXPECT_EQ(reloaded.failures_size(), 0);
  EXPECT_EQ(version(), loaded);
  fs::remove_all(dir);
}

// ism-client stream outlives its server: killed (-9) mid-stream, then shut down with SIGTERM
// mid-stream, each time replaced by a new server on the same port. The client reconnects,
// sends again what had no answer, and ends with a result for every frame.
TEST(Faults, AStreamingClientReconnectsAfterServerRestarts) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ism_faults_stream_" + std::to_string(getpid()));
  fs::create_directories(dir / "depth");
  constexpr int kFrames = 16;
  for (int i = 0; i < kFrames + 2; ++i) {
    // 320x240: slow enough to be caught mid-stream, fast enough for a short test.
    const v1::Scene frame = pngDepthMessage(smallScene(i, 320, 240).depth);
    writeFileBytes((dir / "depth" / (std::to_string(1305031102 + i) + ".5.png")).string(), frame.depth().data());
  }
  auto server = std::make_unique<ServerProcess>();
  const int port = server->port();
  const std::string command = std::string(ISM_CLIENT_BINARY) + " --server " + server->address() +
                              " --deadline-ms 120000 stream --policy every --max-frames " + std::to_string(kFrames) +
                              " --fx 262.5 --fy 262.5 --cx 159.5 --cy 119.5 --folder " + dir.string() + " 2>&1";
  FILE* client = popen(command.c_str(), "r");
  ASSERT_NE(client, nullptr);
  std::string output;
  std::set<int> answered;
  std::map<int, int> answers;
  const std::regex result_line("^frame ([0-9]+): ");
  int restarts = 0;
  char line[4096];
  while (fgets(line, sizeof line, client) != nullptr) {
    output += line;
    std::cmatch match;
    if (!std::regex_search(line, match, result_line)) continue;
    ++answers[std::stoi(match[1])];
    const size_t distinct = answers.size();
    // A crash after the 3rd answer, a graceful stop after the 9th.
    if (restarts == 0 && distinct >= 3) {
      server->kill();
      server = std::make_unique<ServerProcess>(std::vector<std::string>{}, nullptr, port);
      ++restarts;
    } else if (restarts == 1 && distinct >= 9) {
      EXPECT_EQ(server->terminate(), 0);
      server = std::make_unique<ServerProcess>(std::vector<std::string>{}, nullptr, port);
      ++restarts;
    }
  }
  const int status = pclose(client);
  const int exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  fs::remove_all(dir);
  std::cout << output;

  EXPECT_EQ(exit_code, 0) << output;
  EXPECT_EQ(restarts, 2) << output;
  for (int id = 1; id <= kFrames; ++id) EXPECT_EQ(answers[id], 1) << "frame " << id << "\n" << output;
  EXPECT_EQ(answers.size(), static_cast<size_t>(kFrames)) << output;
  EXPECT_NE(output.find("stream broke: UNAVAILABLE"), std::string::npos) << output;
  EXPECT_NE(output.find("the server is shutting down"), std::string::npos) << output;
  EXPECT_TRUE(
      std::regex_search(output, std::regex(std::to_string(kFrames) + " frames sent, [0-9]+ results \\(0 failed\\), "
                                                                     "0 skipped, [2-9] reconnections")))
      << output;
}

// With the server gone for good the client gives up after its attempts, saying so.
TEST(Faults, AStreamingClientGivesUpWhenTheServerStaysAway) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ism_faults_gone_" + std::to_string(getpid()));
  fs::create_directories(dir);
  writeFileBytes((dir / "1.png").string(), pngDepthMessage(smallScene().depth).depth().data());
  int port = 0;
  {
    ServerProcess server;  // a port that was free a moment ago, with nobody listening now
    port = server.port();
  }
  int code = -1;
  const std::string output = runCommand(std::string(ISM_CLIENT_BINARY) + " --server 127.0.0.1:" + std::to_string(port) +
                                            " stream --reconnect-attempts 2 --folder " + dir.string(),
                                        &code);
  fs::remove_all(dir);
  EXPECT_EQ(code, 10 + static_cast<int>(grpc::StatusCode::UNAVAILABLE)) << output;
  EXPECT_NE(output.find("reconnecting in 0.25 s (attempt 1 of 2)"), std::string::npos) << output;
  EXPECT_NE(output.find("reconnecting in 0.50 s (attempt 2 of 2)"), std::string::npos) << output;
  EXPECT_NE(output.find("(gave up after 2 reconnection attempts; 1 frames sent were not answered)"), std::string::npos)
      << output;
}

}  // namespace
}  // namespace ism::testing
