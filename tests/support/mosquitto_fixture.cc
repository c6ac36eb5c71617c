#include "tests/support/mosquitto_fixture.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
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
#include <thread>
#include <utility>

extern char** environ;

namespace fleetgw::testing {
namespace fs = std::filesystem;

namespace {

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

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

// Spawns argv with stdout+stderr appended to `output`; returns the pid.
pid_t spawn(const std::vector<std::string>& argv, const fs::path& output) {
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output.c_str(),
                                   O_WRONLY | O_CREAT | O_APPEND, 0600);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw std::system_error(rc, std::generic_category(), "cannot start " + argv[0]);
  }
  return pid;
}

int wait_exit(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  return status;
}

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
TempDir::TempDir(std::string_view prefix) {
  std::string templ = (fs::temp_directory_path() / (std::string(prefix) + "-XXXXXX")).string();
  if (::mkdtemp(templ.data()) == nullptr) {
    throw std::system_error(errno, std::generic_category(), "mkdtemp " + templ);
  }
  path_ = templ;
}

TempDir::~TempDir() {
  if (path_.empty()) return;
  std::error_code ec;
  fs::remove_all(path_, ec);
}

TempDir::TempDir(TempDir&& other) noexcept : path_(std::exchange(other.path_, {})) {}

TempDir& TempDir::operator=(TempDir&& other) noexcept {
  if (this != &other) {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
    path_ = std::exchange(other.path_, {});
  }
  return *this;
}

// ---------------------------------------------------------------------------------------------
void run_program(const std::vector<std::string>& argv, const fs::path& output_file) {
  const pid_t pid = spawn(argv, output_file);
  const int status = wait_exit(pid);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::string cmd;
    for (const auto& a : argv) cmd += a + " ";
    throw std::runtime_error("command failed: " + cmd + "\n" + read_file(output_file));
  }
}

std::uint16_t free_loopback_port() {
  Fd s{::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)};
  if (s.fd < 0) throw std::system_error(errno, std::generic_category(), "socket");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = 0;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(s.fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    throw std::system_error(errno, std::generic_category(), "bind 127.0.0.1:0");
  }
  socklen_t len = sizeof addr;
  ::getsockname(s.fd, reinterpret_cast<sockaddr*>(&addr), &len);
  return ntohs(addr.sin_port);
}

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
  pid_ = spawn({mosquitto_binary(), "-c", (dir / "mosquitto.conf").string()}, dir / "stdout.log");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw std::runtime_error("mosquitto exited during start-up:\n" + log());
    }
    if (port_accepts(port_)) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  kill();
  throw std::runtime_error("mosquitto did not accept connections within 10 s:\n" + log());
}

void MosquittoBroker::signal_and_wait(int sig) {
  if (!running()) return;
  if (sig != SIGKILL) ::kill(pid_, SIGCONT);  // a paused broker cannot act on SIGTERM
  ::kill(pid_, sig);
  wait_exit(pid_);
  pid_ = -1;
}

void MosquittoBroker::stop() {
  signal_and_wait(SIGTERM);
}
void MosquittoBroker::kill() {
  signal_and_wait(SIGKILL);
}

void MosquittoBroker::pause() {
  if (running()) ::kill(pid_, SIGSTOP);
}

void MosquittoBroker::resume() {
  if (running()) ::kill(pid_, SIGCONT);
}

std::string MosquittoBroker::uri() const {
  return std::string(options_.tls ? "ssl" : "tcp") + "://127.0.0.1:" + std::to_string(port_);
}

std::string MosquittoBroker::uri_localhost() const {
  return std::string(options_.tls ? "ssl" : "tcp") + "://localhost:" + std::to_string(port_);
}

std::string MosquittoBroker::log() const {
  return read_file(dir_.path() / "mosquitto.log") + read_file(dir_.path() / "stdout.log");
}

}  // namespace fleetgw::testing
