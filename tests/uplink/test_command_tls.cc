// `fleetgw command` names why a TLS connect failed (issue 24: it said only "TCP/TLS connect
// failure", while the gateway's uplink already named the cause): an expired broker certificate,
// a broker certificate from a CA the operator does not trust, and one issued for another host
// name, each through a real mosquitto, with the diagnosis the uplink uses
// (gateway/uplink/connect_diagnosis.h).
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>

#include "gateway/command/signing.h"
#include "gateway/tools/operator/command_tool.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/temp_dir.h"
#include "tests/uplink/expired_pki.h"

namespace fleetgw::command {
namespace {

using namespace std::chrono_literals;
using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;

struct ToolRun {
  int exit_code = 0;
  std::string err;
};

ToolRun send_unlock(const std::string& broker_uri, const std::string& ca_file,
                    const std::filesystem::path& dir) {
  std::ostringstream out, err;
  if (!std::filesystem::exists(dir / "operator.pem")) {
    EXPECT_EQ(run_keygen(dir / "operator", out, err), 0) << err.str();
  }
  CommandToolOptions o;
  o.vehicle = "bike-tls";
  o.lock = "seat";
  o.action = "unlock";
  o.key = dir / "operator.pem";
  o.broker = broker_uri;
  o.ca_file = ca_file;
  o.timeout = 5s;
  o.out = &out;
  o.err = &err;
  const int rc = run_command_tool(o);
  return {rc, err.str()};
}

MosquittoOptions tls_broker(const std::filesystem::path& ca, const testing::CertKey& server) {
  MosquittoOptions o;
  o.tls = true;
  o.ca_cert = ca;
  o.server = server;
  o.require_client_cert = false;
  return o;
}

TEST(CommandTls, NamesAnExpiredBrokerCertificate) {
  fleetgw::testing::TempDir dir("fleetgw-cmd-expired");
  const auto pki = fleetgw::testing::make_expired_pki(dir.path());
  MosquittoBroker broker(tls_broker(pki.ca_cert, pki.server));
  broker.start();
  const ToolRun r = send_unlock(broker.uri(), pki.ca_cert.string(), dir.path());
  EXPECT_EQ(r.exit_code, kExitNoAnswer) << r.err;
  EXPECT_NE(r.err.find("TLS: certificate verify failed (certificate has expired)"),
            std::string::npos)
      << r.err;
}

TEST(CommandTls, NamesAnUntrustedBrokerCertificateAndAHostNameMismatch) {
  fleetgw::testing::TempDir dir("fleetgw-cmd-untrusted");
  fleetgw::testing::TestPki pki;
  {
    MosquittoBroker broker(tls_broker(pki.ca_cert(), pki.server()));
    broker.start();
    const ToolRun r = send_unlock(broker.uri(), pki.foreign_ca_cert().string(), dir.path());
    EXPECT_EQ(r.exit_code, kExitNoAnswer) << r.err;
    EXPECT_NE(r.err.find(": TLS: certificate verify failed ("), std::string::npos) << r.err;
  }
  MosquittoBroker broker(tls_broker(pki.ca_cert(), pki.wrong_name_server()));
  broker.start();
  const ToolRun r = send_unlock(broker.uri(), pki.ca_cert().string(), dir.path());
  EXPECT_EQ(r.exit_code, kExitNoAnswer) << r.err;
  EXPECT_NE(r.err.find(": TLS: host name mismatch"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace fleetgw::command
