// TLS, mTLS, bearer tokens and per-client limits of the real ism-server. Certificates come from
// a throwaway CA made with the openssl command in a temporary directory per test process.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "core/common/error.h"
#include "core/io/cloud_io.h"
#include "core/io/file_bytes.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "grpc/reflection/v1alpha/reflection.grpc.pb.h"
#include "server/auth.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;
using v1::FurnitureRecognizer;

constexpr const char* kUserToken = "user-token-5f1c0a9e7d3b";
constexpr const char* kAdminToken = "admin-token-8e2d4b6a0c1f";

class SecurityTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::path(::testing::TempDir()) / ("ism_security_test_" + std::to_string(getpid()));
    fs::create_directories(dir_);
    makeCa("ca");
    makeCa("rogue-ca");
    makeCertificate("server", "ca", "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth");
    makeCertificate("client", "ca", "extendedKeyUsage=clientAuth");
    makeCertificate("rogue-client", "rogue-ca", "extendedKeyUsage=clientAuth");
    // A server certificate that may also identify a client: what `ism-server --health-check`
    // presents to its own server under mTLS.
    makeCertificate("server-and-client", "ca",
                    "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth,clientAuth");
    writeSecret("tokens", std::string("# user tokens\n\n  ") + kUserToken + "  \n");
    writeSecret("admin-tokens", std::string(kAdminToken) + "\n");
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static std::string path(const std::string& name) { return (dir_ / name).string(); }

  static void openssl(const std::string& arguments) {
    int code = 0;
    const std::string output = runCommand("openssl " + arguments, &code);
    ASSERT_EQ(code, 0) << "openssl " << arguments << "\n" << output;
  }
  static void makeCa(const std::string& name) {
    openssl("req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 1 -subj /CN=" + name +
            " -keyout " + path(name + ".key") + " -out " + path(name + ".crt"));
  }
  static void makeCertificate(const std::string& name, const std::string& ca, const std::string& extensions) {
    std::ofstream(path(name + ".ext")) << extensions << "\n";
    openssl("req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj /CN=" + name + " -keyout " +
            path(name + ".key") + " -out " + path(name + ".csr"));
    openssl("x509 -req -days 1 -set_serial " + std::to_string(1000 + name.size()) + " -in " + path(name + ".csr") +
            " -CA " + path(ca + ".crt") + " -CAkey " + path(ca + ".key") + " -extfile " + path(name + ".ext") +
            " -out " + path(name + ".crt"));
  }
  static void writeSecret(const std::string& name, const std::string& text) {
    writeFileBytes(path(name), text);
    chmod(path(name).c_str(), 0600);
  }

  // TLS trusting `ca`, presenting `client`'s certificate when given.
  static std::shared_ptr<grpc::ChannelCredentials> tls(const std::string& ca, const std::string& client = "") {
    grpc::SslCredentialsOptions options;
    options.pem_root_certs = readFileBytes(path(ca + ".crt"));
    if (!client.empty()) {
      options.pem_cert_chain = readFileBytes(path(client + ".crt"));
      options.pem_private_key = readFileBytes(path(client + ".key"));
    }
    return grpc::SslCredentials(options);
  }

  static std::vector<std::string> secureFlags(std::vector<std::string> extra = {}) {
    std::vector<std::string> flags{"--tls-cert",   path("server.crt"), "--tls-key",          path("server.key"),
                                   "--token-file", path("tokens"),     "--admin-token-file", path("admin-tokens")};
    flags.insert(flags.end(), extra.begin(), extra.end());
    return flags;
  }

  static void prepare(grpc::ClientContext* context, const std::string& token) {
    context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
  }

  // A refused handshake ends the call UNAVAILABLE at once; the deadline is for a server that never
  // answers, and is long so that a slow handshake on a busy machine still ends in its refusal.
  static grpc::Status health(const std::shared_ptr<grpc::Channel>& channel) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    grpc::health::v1::HealthCheckResponse response;
    return grpc::health::v1::Health::NewStub(channel)->Check(&context, {}, &response);
  }

  static grpc::Status recognize(const ServerProcess& server, const std::string& token,
                                const v1::Scene& scene = rawDepthMessage(smallScene().depth)) {
    v1::RecognizeRequest request;
    *request.mutable_scene() = scene;
    grpc::ClientContext context;
    prepare(&context, token);
    v1::RecognizeResponse response;
    return FurnitureRecognizer::NewStub(server.channel())->Recognize(&context, request, &response);
  }

  struct Stream {
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReaderWriter<v1::StreamFramesRequest, v1::FrameResult>> call;
  };
  // Sends one empty scene: it fails at once with a per-frame error, so a result proves the
  // stream is open without paying for a recognition.
  static bool openStream(FurnitureRecognizer::Stub& stub, Stream* stream, const std::string& token) {
    prepare(&stream->context, token);
    stream->call = stub.StreamFrames(&stream->context);
    v1::StreamFramesRequest request;
    request.set_frame_id(1);
    request.mutable_scene();
    stream->call->Write(request);
    v1::FrameResult result;
    return stream->call->Read(&result);
  }
  static grpc::Status closeStream(Stream* stream) {
    stream->call->WritesDone();
    v1::FrameResult result;
    while (stream->call->Read(&result)) {
    }
    return stream->call->Finish();
  }

  static fs::path dir_;
};
fs::path SecurityTest::dir_;

TEST_F(SecurityTest, HealthIsOpenAndRecognizeNeedsAToken) {
  ServerProcess server(secureFlags(), tls("ca"));
  EXPECT_TRUE(health(server.channel()).ok());
  {
    grpc::ClientContext context;
    prepare(&context, "");
    auto stub = grpc::reflection::v1alpha::ServerReflection::NewStub(server.channel());
    auto reflection = stub->ServerReflectionInfo(&context);
    grpc::reflection::v1alpha::ServerReflectionRequest request;
    request.set_list_services("");
    ASSERT_TRUE(reflection->Write(request));
    grpc::reflection::v1alpha::ServerReflectionResponse response;
    EXPECT_TRUE(reflection->Read(&response));
    EXPECT_GT(response.list_services_response().service_size(), 0);
  }

  grpc::Status status = recognize(server, "");
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(status.error_message().find("authorization: Bearer <token>"), std::string::npos) << status.error_message();

  status = recognize(server, "not-one-of-the-server-tokens");
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(status.error_message().find("not accepted"), std::string::npos) << status.error_message();

  {
    grpc::ClientContext context;
    prepare(&context, "");
    context.AddMetadata("authorization", std::string("Basic ") + kUserToken);
    v1::ListModelsResponse models;
    status = FurnitureRecognizer::NewStub(server.channel())->ListModels(&context, {}, &models);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }

  status = recognize(server, kUserToken);
  EXPECT_TRUE(status.ok()) << status.error_message();
  status = recognize(server, kAdminToken);
  EXPECT_TRUE(status.ok()) << status.error_message();
}

// Two 'authorization' entries: good then bad, or bad then good. Which one counts would be a
// guess (a proxy in between may take the other), so neither order gets in.
TEST_F(SecurityTest, TwoAuthorizationEntriesAreRefusedInEitherOrder) {
  ServerProcess server(secureFlags(), tls("ca"));
  const std::vector<std::pair<std::string, std::string>> orders{{kUserToken, "not-one-of-the-server-tokens"},
                                                                {"not-one-of-the-server-tokens", kUserToken}};
  for (const auto& [first, second] : orders) {
    grpc::ClientContext context;
    prepare(&context, first);
    context.AddMetadata("authorization", "Bearer " + second);
    v1::ListModelsResponse models;
    const grpc::Status status = FurnitureRecognizer::NewStub(server.channel())->ListModels(&context, {}, &models);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << first << " then " << second;
    EXPECT_NE(status.error_message().find("more than one 'authorization' metadata entry"), std::string::npos)
        << status.error_message();
  }
  EXPECT_TRUE(recognize(server, kUserToken).ok());
}

TEST_F(SecurityTest, ModelManagementNeedsTheAdminToken) {
  ServerProcess server(secureFlags(), tls("ca"));
  auto stub = FurnitureRecognizer::NewStub(server.channel());
  v1::LoadModelRequest load;
  load.set_name("second");
  load.set_path(tinyModelDirectory() + "/default.ismm");
  v1::UnloadModelRequest unload;
  unload.set_name("second");
  v1::ModelInfo model;
  v1::UnloadModelResponse unloaded;
  v1::ReloadModelsResponse reloaded;

  auto call = [&](const std::string& token, auto method, const auto& request, auto* response) {
    grpc::ClientContext context;
    prepare(&context, token);
    return ((*stub).*method)(&context, request, response);
  };
  grpc::Status status = call(kUserToken, &FurnitureRecognizer::Stub::LoadModel, load, &model);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_NE(status.error_message().find("admin token"), std::string::npos) << status.error_message();
  EXPECT_EQ(call(kUserToken, &FurnitureRecognizer::Stub::ReloadModels, v1::ReloadModelsRequest{}, &reloaded)
                .error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(call("", &FurnitureRecognizer::Stub::LoadModel, load, &model).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);

  status = call(kAdminToken, &FurnitureRecognizer::Stub::LoadModel, load, &model);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(model.name(), "second");
  EXPECT_EQ(call(kUserToken, &FurnitureRecognizer::Stub::UnloadModel, unload, &unloaded).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  status = call(kAdminToken, &FurnitureRecognizer::Stub::UnloadModel, unload, &unloaded);
  EXPECT_TRUE(status.ok()) << status.error_message();
}

TEST_F(SecurityTest, WrongCertificateAuthorityFailsTheHandshake) {
  ServerProcess server(secureFlags(), tls("ca"));
  EXPECT_EQ(health(server.channel(tls("rogue-ca"))).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(health(server.channel(grpc::InsecureChannelCredentials())).error_code(), grpc::StatusCode::UNAVAILABLE);
}

TEST_F(SecurityTest, MutualTlsNeedsAClientCertificateFromTheClientCa) {
  ServerProcess server(secureFlags({"--tls-client-ca", path("ca.crt")}), tls("ca", "client"));
  EXPECT_EQ(health(server.channel(tls("ca"))).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(health(server.channel(tls("ca", "rogue-client"))).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_TRUE(health(server.channel(tls("ca", "client"))).ok());

  int code = 0;
  const std::string out = runCommand(std::string(ISM_CLIENT_BINARY) + " --server " + server.address() + " --tls-ca " +
                                         path("ca.crt") + " --tls-cert " + path("client.crt") + " --tls-key " +
                                         path("client.key") + " health",
                                     &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("SERVING"), std::string::npos) << out;
}

TEST_F(SecurityTest, StreamsBeyondThePerClientLimitAreRefused) {
  ServerProcess server(secureFlags({"--max-streams-per-client", "1"}), tls("ca"));
  auto stub = FurnitureRecognizer::NewStub(server.channel());
  Stream first, second, admin, after;
  ASSERT_TRUE(openStream(*stub, &first, kUserToken));
  EXPECT_FALSE(openStream(*stub, &second, kUserToken));
  const grpc::Status refused = closeStream(&second);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(refused.error_message().find("--max-streams-per-client"), std::string::npos) << refused.error_message();
  // Another token is another client.
  EXPECT_TRUE(openStream(*stub, &admin, kAdminToken));
  EXPECT_TRUE(closeStream(&admin).ok());
  EXPECT_TRUE(closeStream(&first).ok());
  // The slot is given back when the stream ends.
  EXPECT_TRUE(openStream(*stub, &after, kUserToken));
  EXPECT_TRUE(closeStream(&after).ok());
}

TEST_F(SecurityTest, WithoutTokensTheStreamLimitCountsPerHost) {
  ServerProcess server({"--max-streams-per-client", "1"});
  auto stub = FurnitureRecognizer::NewStub(server.channel());
  auto other_connection = FurnitureRecognizer::NewStub(server.channel());
  Stream first, second;
  ASSERT_TRUE(openStream(*stub, &first, ""));
  EXPECT_FALSE(openStream(*other_connection, &second, ""));
  EXPECT_EQ(closeStream(&second).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_TRUE(closeStream(&first).ok());
}

TEST_F(SecurityTest, SceneAboveMaxPointsIsResourceExhausted) {
  ServerProcess server(secureFlags({"--max-points", "1000"}), tls("ca"));
  const grpc::Status status = recognize(server, kUserToken, cloudMessage(smallScene().scene));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(status.error_message().find("limit of 1000"), std::string::npos) << status.error_message();
}

TEST_F(SecurityTest, CommandLineClientWithTokenAndCa) {
  ServerProcess server(secureFlags(), tls("ca"));
  savePcd(smallScene().scene, path("scene.pcd"));
  const std::string client =
      std::string(ISM_CLIENT_BINARY) + " --server " + server.address() + " --tls-ca " + path("ca.crt") + " ";
  int code = 0;
  std::string out = runCommand(client + "health", &code);
  EXPECT_EQ(code, 0) << out;
  out = runCommand(client + "--token " + kUserToken + " recognize " + path("scene.pcd"), &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("hypotheses"), std::string::npos) << out;
  out = runCommand(client + "recognize " + path("scene.pcd"), &code);
  EXPECT_EQ(code, 10 + grpc::StatusCode::UNAUTHENTICATED) << out;
  EXPECT_NE(out.find("authorization: Bearer <token>"), std::string::npos) << out;
  out = runCommand(client + "--tls-server-name elsewhere.example health", &code);
  EXPECT_EQ(code, 10 + grpc::StatusCode::UNAVAILABLE) << out;
  out = runCommand("ISM_TOKEN=" + std::string(kUserToken) + " " + client + "models", &code);
  EXPECT_EQ(code, 0) << out;
  out = runCommand("ISM_TOKEN=" + std::string(kUserToken) + " " + client + "models show default", &code);
  EXPECT_EQ(code, 0) << out;
}

TEST_F(SecurityTest, TokenFilesAndCertificatesAreChecked) {
  EXPECT_EQ(server::readTokenFile(path("tokens")), std::vector<std::string>{kUserToken});
  writeSecret("short-token", "# comment\nshort\n");
  writeSecret("no-token", "# only a comment\n\n");
  auto expectError = [](auto load, const std::string& fragment) {
    try {
      load();
      ADD_FAILURE() << "no error; expected one naming " << fragment;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expectError([] { server::readTokenFile(path("short-token")); }, path("short-token") + ":2:");
  expectError([] { server::readTokenFile(path("no-token")); }, path("no-token") + ": no token");
  expectError([] { server::tlsServerCredentials(path("server.crt"), path("client.key"), ""); },
              path("client.key") + ": not the key of the certificate");
  expectError([] { server::tlsServerCredentials(path("server.crt"), path("server.key"), path("tokens")); },
              path("tokens") + ": no PEM certificate");
  EXPECT_NE(server::tlsServerCredentials(path("server.crt"), path("server.key"), path("ca.crt")), nullptr);

  EXPECT_TRUE(server::isLoopbackAddress("127.0.0.1:50051"));
  EXPECT_TRUE(server::isLoopbackAddress("localhost:50051"));
  EXPECT_TRUE(server::isLoopbackAddress("[::1]:50051"));
  EXPECT_TRUE(server::isLoopbackAddress("unix:/run/ism.sock"));
  EXPECT_FALSE(server::isLoopbackAddress("0.0.0.0:50051"));
  EXPECT_FALSE(server::isLoopbackAddress("[::]:50051"));
}

// The image's HEALTHCHECK under TLS: the probe speaks TLS when the server's options name a
// certificate, and with mTLS presents the server's own certificate.
TEST_F(SecurityTest, HealthCheckModeSpeaksTlsAndMutualTls) {
  const std::string probe = std::string(ISM_SERVER_BINARY) + " --health-check";
  int code = 0;
  {
    ServerProcess server(secureFlags(), tls("ca"));
    const std::string tls_flags = " --tls-cert " + path("server.crt") + " --tls-key " + path("server.key");
    std::string out = runCommand(probe + " --listen " + server.address() + tls_flags, &code);
    EXPECT_EQ(code, 0) << out;
    EXPECT_EQ(out, "SERVING\n");
    out = runCommand(probe + " --listen " + server.address(), &code);
    EXPECT_EQ(code, 1) << "plain text against TLS must fail: " << out;
    EXPECT_NE(out.find("failed: UNAVAILABLE"), std::string::npos) << out;
  }
  const std::vector<std::string> mutual{"--tls-cert", path("server-and-client.crt"), "--tls-key",
                                        path("server-and-client.key"), "--tls-client-ca", path("ca.crt")};
  ServerProcess server(mutual, tls("ca", "client"));
  std::string flags;
  for (const auto& flag : mutual) flags += " " + flag;
  const std::string out = runCommand(probe + " --listen " + server.address() + flags, &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out, "SERVING\n");
}

}  // namespace
}  // namespace ism::testing
