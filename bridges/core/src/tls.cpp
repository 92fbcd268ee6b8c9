#include "horus/bridge/tls.hpp"

#include <openssl/ssl.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace horus::bridge {

namespace {

SSL_CTX* native_context(kj::TlsContext& context);

// kj::TlsContext asks clients for a certificate only when they must present one
// (verifyClients); a client that may authenticate otherwise is asked for one without that
// requirement on kj's OpenSSL context, which kj keeps private. An explicit instantiation is the
// one place C++ does not check access, so the member is named there.
template <void* kj::TlsContext::*Member>
struct NativeContextOf {
  friend SSL_CTX* native_context(kj::TlsContext& context) {
    return static_cast<SSL_CTX*>(context.*Member);
  }
};
template struct NativeContextOf<&kj::TlsContext::ctx>;

std::string read_whole(const std::string& path, const std::string& hint) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error("cannot read " + path + hint);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

}  // namespace

TlsCredentials load_tls_credentials(const std::string& folder, const std::string& name) {
  const std::string hint = " (make it with: horus remote keygen " + folder + " " + name + ")";
  const std::string authority = read_whole(folder + "/ca.crt", hint);
  const std::string certificate = read_whole(folder + "/" + name + ".crt", hint);
  const std::string key = read_whole(folder + "/" + name + ".key", hint);
  return TlsCredentials{kj::TlsCertificate(authority),
                        kj::TlsKeypair{kj::TlsPrivateKey(key), kj::TlsCertificate(certificate)}};
}

kj::Own<kj::TlsContext> tls_context(const TlsCredentials& credentials, kj::Timer& timer,
                                    kj::Duration handshake_timeout, ClientCertificates clients) {
  kj::TlsContext::Options options;
  options.useSystemTrustStore = false;
  options.verifyClients = clients == ClientCertificates::Required;
  options.trustedCertificates = kj::arrayPtr(&credentials.authority, 1);
  options.defaultKeypair = credentials.own;
  options.timer = timer;
  options.acceptTimeout = handshake_timeout;
  auto context = kj::heap<kj::TlsContext>(kj::mv(options));
  if (clients == ClientCertificates::Optional) {
    SSL_CTX_set_verify(native_context(*context), SSL_VERIFY_PEER, nullptr);
  }
  return context;
}

std::string handshake_failure(const std::string& why, const HandshakeHints& hints) {
  const auto says = [&why](const char* text) { return why.find(text) != std::string::npos; };
  if (says("peer did not return a certificate")) return "it presented no certificate";
  if (says("certificate verify failed")) return "its certificate does not verify against our CA";
  // The client's alerts: it did not accept our certificate.
  if (says("alert unknown ca")) return "it does not trust our CA: its ca.crt is another's";
  if (says("alert bad certificate") || says("alert certificate unknown")) {
    return "it did not accept our certificate, named '" + hints.server_name +
           "': " + hints.expect_name;
  }
  if (says("wrong version number") || says("http request") || says("packet length too long")) {
    return "it does not speak TLS: " + hints.plain_client;
  }
  return "its TLS handshake failed";
}

}  // namespace horus::bridge
