// Test support: a CA and a server certificate (127.0.0.1 / localhost) that expired in 2020,
// made with the openssl CLI. `openssl x509 -req -days` cannot date a certificate in the past and
// faketime is not available, so the server certificate is signed with `openssl ca`, which takes
// -startdate/-enddate. Used by the TLS tests that check the "expired" diagnosis.
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/support/mosquitto_fixture.h"

namespace fleetgw::testing {

struct ExpiredPki {
  std::filesystem::path ca_cert;
  CertKey server;  // valid for 127.0.0.1 and localhost, notAfter 2020-01-02
};

// Writes the PKI into `dir` (which must exist); throws with openssl's output on failure.
inline ExpiredPki make_expired_pki(const std::filesystem::path& dir) {
  const auto p = [&dir](const char* name) { return (dir / name).string(); };
  const std::string log = p("openssl.log");
  run_program({"openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
               "-nodes", "-keyout", p("ca.key"), "-out", p("ca.crt"), "-days", "2", "-subj",
               "/CN=fleetgw-expired-test-ca"},
              log);
  run_program(
      {"openssl", "req", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes",
       "-keyout", p("server.key"), "-out", p("server.csr"), "-subj", "/CN=127.0.0.1"},
      log);
  std::ofstream(dir / "index.txt").flush();
  std::ofstream(dir / "serial") << "01\n";
  std::ofstream(dir / "ca.cnf") << "[ca]\ndefault_ca = expired\n[expired]\ndir = " << dir.string()
                                << "\ndatabase = " << p("index.txt")
                                << "\nnew_certs_dir = " << dir.string()
                                << "\nserial = " << p("serial")
                                << "\ndefault_md = sha256\npolicy = any\ncopy_extensions = none\n"
                                << "x509_extensions = server\nunique_subject = no\n"
                                << "[any]\ncommonName = supplied\n[server]\n"
                                << "basicConstraints = CA:FALSE\n"
                                << "subjectAltName = IP:127.0.0.1,DNS:localhost\n"
                                << "extendedKeyUsage = serverAuth\n";
  run_program({"openssl", "ca", "-config", p("ca.cnf"), "-batch", "-notext", "-cert", p("ca.crt"),
               "-keyfile", p("ca.key"), "-startdate", "20200101000000Z", "-enddate",
               "20200102000000Z", "-in", p("server.csr"), "-out", p("server.crt")},
              log);
  return {dir / "ca.crt", {dir / "server.crt", dir / "server.key"}};
}

}  // namespace fleetgw::testing
