#include "server/auth.h"

#include <grpcpp/security/server_credentials.h>
#include <openssl/crypto.h>
#include <openssl/pem.h>
#include <openssl/sha.h>
#include <openssl/x509.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <sstream>
#include <string_view>

#include "core/common/error.h"
#include "core/io/file_bytes.h"

namespace ism::server {

namespace {

// Shorter tokens can be guessed by an attacker who may try as often as the server answers.
constexpr size_t kMinTokenLength = 16;

std::string trim(const std::string& text) {
  const size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return "";
  return text.substr(begin, text.find_last_not_of(" \t\r\n") - begin + 1);
}

std::array<uint8_t, 32> sha256(const std::string& text) {
  std::array<uint8_t, 32> digest{};
  SHA256(reinterpret_cast<const unsigned char*>(text.data()), text.size(), digest.data());
  return digest;
}

// "ipv4:10.1.2.3:54321" -> "ipv4:10.1.2.3": a client's connections differ only in the port.
std::string peerHost(const std::string& peer) {
  const size_t colon = peer.rfind(':');
  return colon != std::string::npos && colon > peer.find(':') ? peer.substr(0, colon) : peer;
}

struct BioDeleter {
  void operator()(BIO* bio) const { BIO_free(bio); }
};
struct X509Deleter {
  void operator()(X509* cert) const { X509_free(cert); }
};
struct KeyDeleter {
  void operator()(EVP_PKEY* key) const { EVP_PKEY_free(key); }
};

std::unique_ptr<BIO, BioDeleter> memoryBio(const std::string& pem) {
  return std::unique_ptr<BIO, BioDeleter>(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())));
}

std::unique_ptr<X509, X509Deleter> firstCertificate(const std::string& pem, const std::string& path) {
  std::unique_ptr<X509, X509Deleter> cert(PEM_read_bio_X509(memoryBio(pem).get(), nullptr, nullptr, nullptr));
  if (!cert) throw Error(ErrorCode::kInvalidInput, path + ": no PEM certificate (-----BEGIN CERTIFICATE-----)");
  return cert;
}

}  // namespace

std::vector<std::string> readTokenFile(const std::string& path) {
  std::istringstream lines(readFileBytes(path));
  std::vector<std::string> tokens;
  int number = 0;
  for (std::string line; std::getline(lines, line);) {
    ++number;
    const std::string token = trim(line);
    if (token.empty() || token[0] == '#') continue;
    if (token.size() < kMinTokenLength) {
      throw Error(ErrorCode::kInvalidInput, path + ":" + std::to_string(number) + ": token of " +
                                                std::to_string(token.size()) + " characters; at least " +
                                                std::to_string(kMinTokenLength) + " are needed");
    }
    tokens.push_back(token);
  }
  if (tokens.empty()) throw Error(ErrorCode::kInvalidInput, path + ": no token (one per line, '#' starts a comment)");
  std::error_code ec;
  const auto permissions = std::filesystem::status(path, ec).permissions();
  if (!ec && (permissions & std::filesystem::perms::others_read) != std::filesystem::perms::none) {
    spdlog::warn("{} is readable by every user of this machine: chmod o-r it", path);
  }
  return tokens;
}

std::shared_ptr<grpc::ServerCredentials> tlsServerCredentials(const std::string& cert_path,
                                                              const std::string& key_path,
                                                              const std::string& client_ca_path) {
  grpc::SslServerCredentialsOptions::PemKeyCertPair pair{readFileBytes(key_path), readFileBytes(cert_path)};
  const auto cert = firstCertificate(pair.cert_chain, cert_path);
  std::unique_ptr<EVP_PKEY, KeyDeleter> key(
      PEM_read_bio_PrivateKey(memoryBio(pair.private_key).get(), nullptr, nullptr, nullptr));
  if (!key) throw Error(ErrorCode::kInvalidInput, key_path + ": no unencrypted PEM private key");
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    throw Error(ErrorCode::kInvalidInput, key_path + ": not the key of the certificate in " + cert_path);
  }
  grpc::SslServerCredentialsOptions options(
      client_ca_path.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                             : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  if (!client_ca_path.empty()) {
    options.pem_root_certs = readFileBytes(client_ca_path);
    firstCertificate(options.pem_root_certs, client_ca_path);
  }
  options.pem_key_cert_pairs.push_back(std::move(pair));
  return grpc::SslServerCredentials(options);
}

bool isLoopbackAddress(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0) return true;
  const std::string host = listen.substr(0, listen.rfind(':'));
  return host == "localhost" || host.rfind("127.", 0) == 0 || host == "[::1]";
}

StreamSlot::~StreamSlot() { owner_.release(client_); }

AccessControl::AccessControl(const AccessParams& params) : max_streams_per_client_(params.max_streams_per_client) {
  for (size_t i = 0; i < params.tokens.size(); ++i) {
    tokens_.push_back({sha256(params.tokens[i]), false, "token " + std::to_string(i + 1)});
  }
  for (size_t i = 0; i < params.admin_tokens.size(); ++i) {
    tokens_.push_back({sha256(params.admin_tokens[i]), true, "admin token " + std::to_string(i + 1)});
  }
}

grpc::Status AccessControl::authorize(const grpc::ServerContextBase& context, const char* rpc, Access needed) const {
  std::string client;
  return check(context, rpc, needed, &client);
}

grpc::Status AccessControl::check(const grpc::ServerContextBase& context, const char* rpc, Access needed,
                                  std::string* client) const {
  if (!authEnabled()) {
    *client = "host " + peerHost(context.peer());
    return grpc::Status::OK;
  }
  const auto& metadata = context.client_metadata();
  const auto header = metadata.find("authorization");
  if (header == metadata.end()) {
    return {grpc::StatusCode::UNAUTHENTICATED,
            std::string(rpc) + " needs a token: send the metadata 'authorization: Bearer <token>'"};
  }
  // Which of several would count is a guess a proxy in between may make differently.
  if (metadata.count("authorization") > 1) {
    return {grpc::StatusCode::UNAUTHENTICATED,
            std::string(rpc) + ": more than one 'authorization' metadata entry; send exactly one"};
  }
  const std::string value(header->second.data(), header->second.size());
  constexpr std::string_view kScheme = "bearer ";
  const bool bearer = value.size() > kScheme.size() &&
                      std::equal(kScheme.begin(), kScheme.end(), value.begin(),
                                 [](char a, char b) { return a == std::tolower(static_cast<unsigned char>(b)); });
  if (!bearer) {
    return {grpc::StatusCode::UNAUTHENTICATED,
            std::string(rpc) + ": the 'authorization' metadata must read 'Bearer <token>'"};
  }
  // Digests of equal length compared without an early exit: the time taken tells nothing about
  // how much of a guess was right, nor which token matched.
  const auto digest = sha256(trim(value.substr(kScheme.size())));
  const Token* match = nullptr;
  for (const auto& token : tokens_) {
    if (CRYPTO_memcmp(digest.data(), token.sha256.data(), digest.size()) == 0) match = &token;
  }
  if (match == nullptr) {
    return {grpc::StatusCode::UNAUTHENTICATED,
            std::string(rpc) + ": the token in 'authorization: Bearer <token>' is not accepted"};
  }
  if (needed == Access::kAdmin && !match->admin) {
    return {grpc::StatusCode::PERMISSION_DENIED,
            std::string(rpc) + " needs an admin token (--admin-token-file); " + match->name + " is not one"};
  }
  *client = match->name;
  return grpc::Status::OK;
}

grpc::Status AccessControl::openStream(const grpc::ServerContextBase& context, std::unique_ptr<StreamSlot>* slot) {
  std::string client;
  const grpc::Status status = check(context, "StreamFrames", Access::kUser, &client);
  if (!status.ok() || max_streams_per_client_ == 0) return status;
  std::lock_guard lock(mutex_);
  size_t& open = open_streams_[client];
  if (open >= max_streams_per_client_) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            client + " already has " + std::to_string(open) +
                " open StreamFrames calls, the server's limit per client (--max-streams-per-client)"};
  }
  ++open;
  *slot = std::make_unique<StreamSlot>(*this, client);
  return grpc::Status::OK;
}

void AccessControl::release(const std::string& client) {
  std::lock_guard lock(mutex_);
  const auto it = open_streams_.find(client);
  if (--it->second == 0) open_streams_.erase(it);
}

}  // namespace ism::server
