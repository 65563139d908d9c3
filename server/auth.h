#pragma once
// Who may call what. Bearer tokens are checked at the start of every FurnitureRecognizer RPC;
// the health and reflection services are separate services and stay open (Kubernetes probes,
// grpcurl). Admin tokens are needed for the RPCs that change which models are loaded. Each
// client (its token when auth is on, else its host) may hold a bounded number of streams.
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_context.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace ism::server {

// The tokens in `path`, one per line; surrounding blanks, empty lines and '#' comments are
// skipped. Throws ism::Error naming the file when it cannot be read or holds no token.
std::vector<std::string> readTokenFile(const std::string& path);

// TLS with the PEM certificate chain and key; with `client_ca_path`, clients must present a
// certificate signed by it (mTLS). Throws ism::Error naming the file that is missing, does not
// parse, or whose key does not belong to the certificate (gRPC itself would only fail to listen).
std::shared_ptr<grpc::ServerCredentials> tlsServerCredentials(const std::string& cert_path,
                                                              const std::string& key_path,
                                                              const std::string& client_ca_path);

// True for "localhost:…", "127.x.x.x:…", "[::1]:…" and unix sockets: addresses no other machine reaches.
bool isLoopbackAddress(const std::string& listen);

enum class Access { kUser, kAdmin };

struct AccessParams {
  std::vector<std::string> tokens;        // may call every RPC but the admin ones
  std::vector<std::string> admin_tokens;  // may call every RPC
  size_t max_streams_per_client = 0;      // concurrent StreamFrames calls; 0: unlimited
};

class AccessControl;

// One client's stream slot; gives it back when destroyed.
class StreamSlot {
 public:
  StreamSlot(AccessControl& owner, std::string client) : owner_(owner), client_(std::move(client)) {}
  ~StreamSlot();
  StreamSlot(const StreamSlot&) = delete;
  StreamSlot& operator=(const StreamSlot&) = delete;

 private:
  AccessControl& owner_;
  const std::string client_;
};

class AccessControl {
 public:
  explicit AccessControl(const AccessParams& params);

  // False when no token is configured: every caller is let in.
  bool authEnabled() const { return !tokens_.empty(); }

  // OK, UNAUTHENTICATED (no, malformed or unknown token) or PERMISSION_DENIED (a user token
  // on an admin RPC). `rpc` names the call in the message.
  grpc::Status authorize(const grpc::ServerContextBase& context, const char* rpc, Access needed) const;

  // authorize(kUser) and then a stream slot, held by `slot` until the stream ends;
  // RESOURCE_EXHAUSTED when the client already holds max_streams_per_client.
  grpc::Status openStream(const grpc::ServerContextBase& context, std::unique_ptr<StreamSlot>* slot);

 private:
  friend class StreamSlot;
  struct Token {
    std::array<uint8_t, 32> sha256;
    bool admin;
    std::string name;  // "token 2", "admin token 1": for logs and limits, never the secret
  };
  // The caller's identity into `client` (the token's name, or the peer host when auth is off).
  grpc::Status check(const grpc::ServerContextBase& context, const char* rpc, Access needed,
                     std::string* client) const;
  void release(const std::string& client);

  std::vector<Token> tokens_;
  const size_t max_streams_per_client_;
  std::mutex mutex_;
  std::map<std::string, size_t> open_streams_;
};

}  // namespace ism::server
