// TLS of the bridges that speak it (the remote link, the live view's wss://), with the
// certificate folder `horus remote keygen DIR NAME` makes: DIR/ca.crt (the one authority trusted),
// DIR/NAME.crt and DIR/NAME.key (this end's own). On kj-tls, so not in horus::bridge_core (which
// links no Cap'n Proto): src/tls.cpp is compiled into each bridge that speaks TLS, with
// CapnProto::kj-tls and OpenSSL::SSL.
#pragma once

#include <kj/compat/tls.h>
#include <kj/timer.h>

#include <string>

namespace horus::bridge {

struct TlsCredentials {
  kj::TlsCertificate authority;
  kj::TlsKeypair own;
};

/// DIR/ca.crt and DIR/NAME.{crt,key}. Throws std::runtime_error naming the file that is missing
/// or unreadable, and the keygen command that makes it.
TlsCredentials load_tls_credentials(const std::string& folder, const std::string& name);

/// What a server asks of its clients' certificates. A certificate presented is always checked
/// against the folder's CA (a client whose certificate does not verify fails the handshake).
enum class ClientCertificates {
  /// Every client presents one (the remote link: its common name is the peer).
  Required,
  /// A client may present one or not (a live view: a client without one gives a token).
  Optional,
};

/// TLS that trusts only the folder's CA and presents this end's own certificate; a handshake
/// that takes longer than `handshake_timeout` fails.
kj::Own<kj::TlsContext> tls_context(const TlsCredentials& credentials, kj::Timer& timer,
                                    kj::Duration handshake_timeout,
                                    ClientCertificates clients = ClientCertificates::Required);

/// What a server adds to a failed handshake's reason, in its own words.
struct HandshakeHints {
  /// The name in this server's certificate.
  std::string server_name;
  /// How a client that connects by address is made to expect that name.
  std::string expect_name;
  /// What a client that does not speak TLS probably is.
  std::string plain_client;
};

/// What a server's failed TLS handshake says of the client, from OpenSSL's text `why` (the kj
/// exception's description): "its certificate does not verify against our CA", "it does not
/// speak TLS: <plain_client>", ...
std::string handshake_failure(const std::string& why, const HandshakeHints& hints);

}  // namespace horus::bridge
