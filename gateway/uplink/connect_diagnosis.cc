#include "gateway/uplink/connect_diagnosis.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509_vfy.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>
#include <utility>

#include "gateway/uplink/mqtt_connection.h"
#include "gateway/uplink/tcp_nodelay.h"

namespace fleetgw::uplink {

namespace {

// Owns a socket descriptor.
class Fd {
 public:
  explicit Fd(int fd = -1) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  Fd& operator=(Fd&& o) noexcept {
    std::swap(fd_, o.fd_);
    return *this;
  }
  int get() const { return fd_; }
  explicit operator bool() const { return fd_ >= 0; }

 private:
  int fd_;
};

struct AddrInfoFree {
  void operator()(addrinfo* a) const { ::freeaddrinfo(a); }
};
struct SslCtxFree {
  void operator()(SSL_CTX* c) const { SSL_CTX_free(c); }
};
struct SslFree {
  void operator()(SSL* s) const { SSL_free(s); }
};

std::string errno_text(int err) {
  char buf[128];
  return ::strerror_r(err, buf, sizeof buf);
}

std::string openssl_error() {
  const unsigned long e = ERR_peek_last_error();
  ERR_clear_error();
  if (e == 0) return "no OpenSSL error; the peer closed the connection";
  const char* reason = ERR_reason_error_string(e);
  return reason != nullptr ? reason : "OpenSSL error " + std::to_string(e);
}

// Connects to one address within `timeout`; on failure sets `error` to errno.
Fd connect_one(const addrinfo& ai, std::chrono::milliseconds timeout, int& error) {
  Fd fd(::socket(ai.ai_family, ai.ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, ai.ai_protocol));
  if (!fd) {
    error = errno;
    return Fd();
  }
  if (::connect(fd.get(), ai.ai_addr, ai.ai_addrlen) != 0) {
    if (errno != EINPROGRESS) {
      error = errno;
      return Fd();
    }
    pollfd p{fd.get(), POLLOUT, 0};
    const int n = ::poll(&p, 1, static_cast<int>(timeout.count()));
    if (n <= 0) {
      error = n == 0 ? ETIMEDOUT : errno;
      return Fd();
    }
    int so_error = 0;
    socklen_t len = sizeof so_error;
    ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &so_error, &len);
    if (so_error != 0) {
      error = so_error;
      return Fd();
    }
  }
  // Blocking from here on, with the same bound on every read and write of the handshake.
  ::fcntl(fd.get(), F_SETFL, ::fcntl(fd.get(), F_GETFL) & ~O_NONBLOCK);
  timeval tv{static_cast<time_t>(timeout.count() / 1000),
             static_cast<suseconds_t>((timeout.count() % 1000) * 1000)};
  ::setsockopt(fd.get(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd.get(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  return fd;
}

std::string tls_handshake(int fd, const ProbeTarget& t) {
  const TlsConfig& tls = *t.tls;
  std::unique_ptr<SSL_CTX, SslCtxFree> ctx(SSL_CTX_new(TLS_client_method()));
  if (!ctx) return "TLS: handshake failed (" + openssl_error() + ")";
  SSL_CTX_set_min_proto_version(ctx.get(), TLS1_2_VERSION);
  SSL_CTX_set_verify(ctx.get(), SSL_VERIFY_PEER, nullptr);
  if (tls.ca_file.empty()) {
    SSL_CTX_set_default_verify_paths(ctx.get());
  } else if (SSL_CTX_load_verify_locations(ctx.get(), tls.ca_file.c_str(), nullptr) != 1) {
    return "TLS: cannot load CA file (" + openssl_error() + ")";
  }
  if (!tls.cert_file.empty()) {
    if (SSL_CTX_use_certificate_chain_file(ctx.get(), tls.cert_file.c_str()) != 1) {
      return "TLS: cannot load client certificate (" + openssl_error() + ")";
    }
    if (SSL_CTX_use_PrivateKey_file(ctx.get(), tls.key_file.c_str(), SSL_FILETYPE_PEM) != 1) {
      return "TLS: cannot load client key (" + openssl_error() + ")";
    }
  }
  std::unique_ptr<SSL, SslFree> ssl(SSL_new(ctx.get()));
  if (!ssl) return "TLS: handshake failed (" + openssl_error() + ")";
  SSL_set_fd(ssl.get(), fd);
  in6_addr ip{};
  const bool is_ip = ::inet_pton(AF_INET, t.host.c_str(), &ip) == 1 ||
                     ::inet_pton(AF_INET6, t.host.c_str(), &ip) == 1;
  if (!is_ip) SSL_set_tlsext_host_name(ssl.get(), t.host.c_str());
  if (tls.verify_server_name) {
    X509_VERIFY_PARAM* param = SSL_get0_param(ssl.get());
    if (is_ip) {
      X509_VERIFY_PARAM_set1_ip_asc(param, t.host.c_str());
    } else {
      X509_VERIFY_PARAM_set1_host(param, t.host.c_str(), 0);
    }
  }
  ERR_clear_error();
  const int rc = SSL_connect(ssl.get());
  const long verify = SSL_get_verify_result(ssl.get());
  if (verify == X509_V_ERR_HOSTNAME_MISMATCH || verify == X509_V_ERR_IP_ADDRESS_MISMATCH) {
    ERR_clear_error();
    return "TLS: host name mismatch";
  }
  if (verify != X509_V_OK) {
    ERR_clear_error();
    return "TLS: certificate verify failed (" + std::string(X509_verify_cert_error_string(verify)) +
           ")";
  }
  if (rc != 1) return "TLS: handshake failed (" + openssl_error() + ")";
  SSL_shutdown(ssl.get());
  return {};
}

}  // namespace

std::optional<ProbeTarget> probe_target(std::string_view broker_uri,
                                        const std::optional<TlsConfig>& tls) {
  const std::string uri = normalise_broker_uri(broker_uri);
  const bool secure = uri.rfind("ssl://", 0) == 0;
  if (!secure && uri.rfind("tcp://", 0) != 0) return std::nullopt;
  const auto port = broker_port(uri);
  if (!port) return std::nullopt;
  std::string_view rest = std::string_view(uri).substr(6);
  rest = rest.substr(0, rest.find_first_of("/?#"));
  if (const auto at = rest.rfind('@'); at != std::string_view::npos) rest.remove_prefix(at + 1);
  std::string_view host;
  if (!rest.empty() && rest.front() == '[') {
    host = rest.substr(1, rest.find(']') - 1);
  } else {
    host = rest.substr(0, rest.rfind(':'));
  }
  if (host.empty()) return std::nullopt;
  ProbeTarget t{std::string(host), *port, std::nullopt};
  if (secure) t.tls = tls.value_or(TlsConfig{});
  return t;
}

std::string diagnose_connect(const ProbeTarget& t, std::chrono::milliseconds timeout) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int gai = ::getaddrinfo(t.host.c_str(), std::to_string(t.port).c_str(), &hints, &found);
  if (gai != 0) return "host not found (" + std::string(::gai_strerror(gai)) + ")";
  const std::unique_ptr<addrinfo, AddrInfoFree> list(found);
  int error = 0;
  Fd fd;
  for (const addrinfo* ai = list.get(); ai != nullptr && !fd; ai = ai->ai_next) {
    fd = connect_one(*ai, timeout, error);
  }
  if (!fd) {
    if (error == ECONNREFUSED) return "connection refused";
    return "unreachable (" + errno_text(error) + ")";
  }
  if (!t.tls) return {};
  return tls_handshake(fd.get(), t);
}

bool is_tls_failure(std::string_view reason) {
  return reason.substr(0, 4) == "TLS:";
}

}  // namespace fleetgw::uplink
