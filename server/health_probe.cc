#include "server/health_probe.h"

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/security/tls_certificate_provider.h>
#include <grpcpp/security/tls_certificate_verifier.h>
#include <grpcpp/security/tls_credentials_options.h>

#include <exception>
#include <ostream>

#include "core/io/file_bytes.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "server/status_mapping.h"

namespace ism::server {
namespace {

std::shared_ptr<grpc::ChannelCredentials> probeCredentials(const ServerOptions& options) {
  if (options.tls_cert.empty()) return grpc::InsecureChannelCredentials();
  grpc::experimental::TlsChannelCredentialsOptions tls;
  // The probe reaches its own host, not a server a client chose by name: it needs a TLS
  // handshake, not proof of who answers, and it may not have the CA that signed the server.
  tls.set_verify_server_certs(false);
  tls.set_check_call_host(false);
  tls.set_certificate_verifier(std::make_shared<grpc::experimental::NoOpCertificateVerifier>());
  if (!options.tls_client_ca.empty()) {
    std::vector<grpc::experimental::IdentityKeyCertPair> identity{
        {readFileBytes(options.tls_key), readFileBytes(options.tls_cert)}};
    tls.set_certificate_provider(std::make_shared<grpc::experimental::StaticDataCertificateProvider>(identity));
    tls.watch_identity_key_cert_pairs();
  }
  return grpc::experimental::TlsCredentials(tls);
}

}  // namespace

std::string probeAddress(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0) return listen;
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos) return listen;
  const std::string host = listen.substr(0, colon), port = listen.substr(colon + 1);
  if (host.empty() || host == "0.0.0.0") return "127.0.0.1:" + port;
  if (host == "[::]" || host == "[::0]") return "[::1]:" + port;
  return listen;
}

int runHealthCheck(const ServerOptions& options, std::chrono::milliseconds deadline, std::ostream& out,
                   std::ostream& err) {
  const std::string address = probeAddress(options.listen);
  try {
    auto stub = grpc::health::v1::Health::NewStub(grpc::CreateChannel(address, probeCredentials(options)));
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + deadline);
    grpc::health::v1::HealthCheckResponse response;
    const grpc::Status status = stub->Check(&context, {}, &response);
    if (!status.ok()) {
      err << "health check of " << address << " failed: " << statusCodeName(status.error_code()) << ": " << status.error_message()
          << "\n";
      return 1;
    }
    out << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()) << "\n";
    if (response.status() == grpc::health::v1::HealthCheckResponse::SERVING) return 0;
    err << "health check of " << address << ": the server is not serving\n";
    return 1;
  } catch (const std::exception& e) {  // the TLS files of the options cannot be read
    err << "health check of " << address << ": " << e.what() << "\n";
    return 1;
  }
}

}  // namespace ism::server
