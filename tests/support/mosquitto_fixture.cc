#include "tests/support/mosquitto_fixture.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "tests/support/wait.h"

namespace fleetgw::testing {
namespace fs = std::filesystem;

namespace {

void write_file(const fs::path& p, std::string_view text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + p.string());
}

// Closes a file descriptor on scope exit.
struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

std::string mosquitto_binary() {
  for (const char* candidate : {"/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto"}) {
    if (::access(candidate, X_OK) == 0) return candidate;
  }
  return "mosquitto";  // rely on PATH
}

bool port_accepts(std::uint16_t port) {
  Fd s{::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)};
  if (s.fd < 0) return false;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return ::connect(s.fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
TestPki::TestPki() : dir_("fleetgw-pki") {
  ca_ = make_ca("ca", "fleetgw test CA");
  foreign_ca_ = make_ca("foreign-ca", "unrelated CA");
  server_ = issue("server", "localhost",
                  "subjectAltName=DNS:localhost,IP:127.0.0.1\nextendedKeyUsage=serverAuth\n");
  wrong_server_ = issue("wrong-server", "wrong-host.invalid",
                        "subjectAltName=DNS:wrong-host.invalid\nextendedKeyUsage=serverAuth\n");
}

CertKey TestPki::make_ca(std::string_view name, std::string_view cn) {
  const fs::path dir = dir_.path();
  CertKey ca{dir / (std::string(name) + ".crt"), dir / (std::string(name) + ".key")};
  run_program({"openssl",
               "req",
               "-x509",
               "-newkey",
               "ec",
               "-pkeyopt",
               "ec_paramgen_curve:prime256v1",
               "-nodes",
               "-keyout",
               ca.key.string(),
               "-out",
               ca.cert.string(),
               "-days",
               "2",
               "-subj",
               "/CN=" + std::string(cn),
               "-addext",
               "basicConstraints=critical,CA:TRUE",
               "-addext",
               "keyUsage=critical,keyCertSign,cRLSign"},
              dir / "openssl.log");
  return ca;
}

CertKey TestPki::issue(std::string_view name, std::string_view cn, std::string_view extensions) {
  const fs::path dir = dir_.path();
  const std::string base = (dir / std::string(name)).string();
  CertKey out{base + ".crt", base + ".key"};
  write_file(base + ".ext", extensions);
  run_program({"openssl", "req", "-new", "-newkey", "ec", "-pkeyopt",
               "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", out.key.string(), "-out",
               base + ".csr", "-subj", "/CN=" + std::string(cn)},
              dir / "openssl.log");
  run_program({"openssl", "x509", "-req", "-in", base + ".csr", "-CA", ca_.cert.string(), "-CAkey",
               ca_.key.string(), "-CAcreateserial", "-out", out.cert.string(), "-days", "2",
               "-extfile", base + ".ext"},
              dir / "openssl.log");
  return out;
}

CertKey TestPki::issue_client(std::string_view common_name) {
  for (char c : common_name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') {
      throw std::invalid_argument("client certificate name must be [A-Za-z0-9._-]: " +
                                  std::string(common_name));
    }
  }
  return issue("client-" + std::string(common_name), common_name, "extendedKeyUsage=clientAuth\n");
}

// ---------------------------------------------------------------------------------------------
MosquittoBroker::MosquittoBroker(MosquittoOptions options)
    : options_(std::move(options)), dir_("fleetgw-mosquitto"), port_(free_loopback_port()) {
  if (options_.tls && (options_.server.cert.empty() || options_.server.key.empty())) {
    throw std::invalid_argument("MosquittoOptions: tls needs a server certificate and key");
  }
  write_config();
}

MosquittoBroker::~MosquittoBroker() {
  try {
    if (running()) kill();
  } catch (...) {
    // Destructor: the process is gone or unkillable; nothing sensible left to do.
  }
}

void MosquittoBroker::write_config() const {
  const fs::path dir = dir_.path();
  std::ostringstream c;
  // The broker runs as the test's own user: as root, mosquitto would otherwise switch to the
  // "mosquitto" user and lose access to the private temporary directory.
  if (::geteuid() == 0) c << "user root\n";
  c << "log_dest file " << (dir / "mosquitto.log").string() << "\n"
    << "log_type all\n"
    << "listener " << port_ << " 127.0.0.1\n"
    << "max_inflight_messages 0\n"
    << "max_queued_messages 100000\n"
    << "set_tcp_nodelay " << (options_.tcp_nodelay ? "true" : "false") << "\n";
  if (options_.persistence) {
    c << "persistence true\n"
      << "persistence_location " << (dir / "").string() << "\n"
      << "autosave_interval 1\n";
  } else {
    c << "persistence false\n";
  }
  if (options_.tls) {
    c << "certfile " << options_.server.cert.string() << "\n"
      << "keyfile " << options_.server.key.string() << "\n"
      << "tls_version tlsv1.2\n";
    if (!options_.ca_cert.empty()) c << "cafile " << options_.ca_cert.string() << "\n";
    if (options_.require_client_cert) {
      c << "require_certificate true\nuse_identity_as_username true\n";
    }
  }
  if (!options_.acl.empty()) {
    write_file(dir / "acl", options_.acl);
    c << "acl_file " << (dir / "acl").string() << "\n";
  }
  c << "allow_anonymous " << (options_.tls && options_.require_client_cert ? "false" : "true")
    << "\n";
  c << options_.extra_config << "\n";
  write_file(dir / "mosquitto.conf", c.str());
}

void MosquittoBroker::start() {
  if (running()) return;
  const fs::path dir = dir_.path();
  process_.emplace(
      std::vector<std::string>{mosquitto_binary(), "-c", (dir / "mosquitto.conf").string()},
      dir / "stdout.log");
  bool exited = false;
  const bool up = wait_until(
      [&] {
        exited = !process_->running();
        return exited || port_accepts(port_);
      },
      std::chrono::seconds(10));
  if (exited) {
    process_.reset();
    throw std::runtime_error("mosquitto exited during start-up:\n" + log());
  }
  if (!up) {
    kill();
    throw std::runtime_error("mosquitto did not accept connections within 10 s:\n" + log());
  }
}

void MosquittoBroker::stop() {
  if (!running()) return;
  // SIGTERM before SIGCONT: a paused broker then stops on waking, before it reads what its
  // clients sent meanwhile (SIGCONT first left it a turn to acknowledge all of it, and a loaded
  // machine gave it that turn before the SIGTERM came).
  process_->signal(SIGTERM);
  process_->signal(SIGCONT);
  process_->stop(std::chrono::seconds(30));
  process_.reset();
}

void MosquittoBroker::kill() {
  if (!running()) return;
  process_->kill();
  process_.reset();
}

void MosquittoBroker::pause() {
  if (running()) process_->signal(SIGSTOP);
}

void MosquittoBroker::resume() {
  if (running()) process_->signal(SIGCONT);
}

std::string MosquittoBroker::uri() const {
  return std::string(options_.tls ? "ssl" : "tcp") + "://127.0.0.1:" + std::to_string(port_);
}

std::string MosquittoBroker::uri_localhost() const {
  return std::string(options_.tls ? "ssl" : "tcp") + "://localhost:" + std::to_string(port_);
}

std::string MosquittoBroker::log() const {
  return read_text_file(dir_.path() / "mosquitto.log") + read_text_file(dir_.path() / "stdout.log");
}

}  // namespace fleetgw::testing
