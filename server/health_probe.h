#pragma once
// `ism-server --health-check`: the container's HEALTHCHECK, so that the image needs no client
// binary (ism-client links PCL's file formats and OpenNI, hundreds of MB of libraries). It asks
// the grpc.health.v1 service of the server that the same options (ISM_LISTEN, ISM_TLS_*) describe.
#include <chrono>
#include <iosfwd>
#include <string>

#include "server/options.h"

namespace ism::server {

// Where a probe on this machine reaches a server listening on `listen`: a wildcard host
// (0.0.0.0, [::], none) becomes the loopback address of its family; anything else is kept.
std::string probeAddress(const std::string& listen);

// Asks the health service "" (the process) of the server `options` describes. TLS when
// options.tls_cert is set: the probe talks to its own host, so it checks no server certificate;
// with --tls-client-ca it presents the server's own certificate and key (which that CA must
// have signed). Prints the status to `out`; returns 0 for SERVING, else 1 with the reason on `err`.
int runHealthCheck(const ServerOptions& options, std::chrono::milliseconds deadline, std::ostream& out,
                   std::ostream& err);

}  // namespace ism::server
