// Test support: a real mosquitto broker for integration tests and benchmarks (TempDir,
// run_program and free_loopback_port come with it from temp_dir.h and process.h).
//
// Contract:
//  * MosquittoBroker starts `mosquitto -c <generated config>` listening on 127.0.0.1 at a free
//    port, in a private temporary directory (config, log file, ACL, persistence). start() returns
//    once the port accepts connections, or throws std::runtime_error quoting the broker log.
//  * stop()/kill() end the process (SIGTERM / SIGKILL); start() again reuses the same port and
//    directory, so "broker outage, then back" is one stop() + start(). pause()/resume() freeze the
//    broker (SIGSTOP/SIGCONT): connections stay open but nothing is acknowledged. stop() of a
//    paused broker acknowledges nothing more either (call it without resume() first).
//  * TestPki generates, with the openssl CLI, a CA, a server certificate for 127.0.0.1/localhost,
//    a server certificate for a different host name (to test host-name verification), and client
//    certificates whose common name is the given identity.
//  * Everything is removed when the object is destroyed; the destructor never throws.
//  * Not thread-safe: drive one instance from one thread.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing {

// A certificate and its private key (PEM files).
struct CertKey {
  std::filesystem::path cert;
  std::filesystem::path key;
};

// Test certificate authority and certificates, made with the openssl CLI (EC P-256, 2 days).
class TestPki {
 public:
  // Generates the CA and both server certificates in a new temporary directory.
  TestPki();

  const std::filesystem::path& ca_cert() const { return ca_.cert; }
  // Server certificate valid for 127.0.0.1 and localhost.
  const CertKey& server() const { return server_; }
  // Server certificate signed by the same CA but only valid for "wrong-host.invalid".
  const CertKey& wrong_name_server() const { return wrong_server_; }
  // Issues a client certificate with CN = `common_name` (mosquitto's use_identity_as_username).
  CertKey issue_client(std::string_view common_name);
  // A second, unrelated CA (a client trusting only this one must refuse the broker).
  const std::filesystem::path& foreign_ca_cert() const { return foreign_ca_.cert; }

 private:
  CertKey make_ca(std::string_view name, std::string_view cn);
  CertKey issue(std::string_view name, std::string_view cn, std::string_view extensions);

  TempDir dir_;
  CertKey ca_;
  CertKey foreign_ca_;
  CertKey server_;
  CertKey wrong_server_;
};

struct MosquittoOptions {
  // TLS listener; needs `server` (and `ca_cert` to verify client certificates).
  bool tls = false;
  std::filesystem::path ca_cert;
  CertKey server;
  // With TLS: clients must present a certificate signed by ca_cert; its CN becomes the username.
  bool require_client_cert = true;
  // Contents of an ACL file (mosquitto acl_file syntax); empty = no ACL, anonymous allowed.
  std::string acl;
  // Keep broker state on disk across stop()/start() (retained messages, sessions).
  bool persistence = false;
  // set_tcp_nodelay, as deploy/mosquitto/mosquitto.conf recommends; false = mosquitto's default
  // (Nagle on).
  bool tcp_nodelay = true;
  // Extra lines appended to the generated config.
  std::string extra_config;
};

class MosquittoBroker {
 public:
  explicit MosquittoBroker(MosquittoOptions options = {});
  ~MosquittoBroker();
  MosquittoBroker(const MosquittoBroker&) = delete;
  MosquittoBroker& operator=(const MosquittoBroker&) = delete;

  // Starts the broker (no-op if running). Throws std::runtime_error with the log on failure.
  void start();
  // Graceful stop (SIGTERM), waits for exit.
  void stop();
  // Abrupt stop (SIGKILL), waits for exit.
  void kill();
  // Freezes / thaws the broker process.
  void pause();
  void resume();
  bool running() const { return process_.has_value(); }

  std::uint16_t port() const { return port_; }
  // "tcp://127.0.0.1:<port>" or "ssl://127.0.0.1:<port>".
  std::string uri() const;
  // Same with host name "localhost" (for host-name verification tests).
  std::string uri_localhost() const;
  // Broker log so far (for failure messages).
  std::string log() const;
  const std::filesystem::path& directory() const { return dir_.path(); }

 private:
  void write_config() const;

  MosquittoOptions options_;
  TempDir dir_;
  std::uint16_t port_ = 0;
  std::optional<ChildProcess> process_;
};

}  // namespace fleetgw::testing
