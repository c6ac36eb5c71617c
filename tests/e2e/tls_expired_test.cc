// Issue 11: TLS failure reasons reach the technician. The real `fleetgw run` against a real
// mosquitto whose server certificate expired (right CA, right host name): the log and
// `fleetgw status` (text and JSON) say "expired", and status needs attention (exit 1).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "tests/support/files.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/expired_pki.h"

namespace {

using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::MosquittoOptions;
using fleetgw::testing::TempDir;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

using ::fleetgw::testing::read_text_file;
int fleetgw(std::vector<std::string> args, const fs::path& out) {
  args.insert(args.begin(), FLEETGW_BINARY);
  fs::remove(out);
  return fleetgw::testing::run_for_exit_code(args, out);
}

TEST(TlsStatus, ExpiredServerCertificateIsNamedInLogAndStatus) {
  TempDir dir("fleetgw-tls-expired");
  fs::create_directories(dir.path() / "pki");
  const auto pki = fleetgw::testing::make_expired_pki(dir.path() / "pki");
  MosquittoOptions o;
  o.tls = true;
  o.ca_cert = pki.ca_cert;
  o.server = pki.server;
  o.require_client_cert = false;
  MosquittoBroker broker(o);
  broker.start();
  std::string uri = broker.uri();
  ASSERT_EQ(uri.rfind("ssl://", 0), 0u) << uri;

  std::ofstream(dir.path() / "quiet.toml") << "[scenario]\nname = \"quiet\"\nduration_s = 3600\n"
                                           << "[[ride]]\nduration_s = 3600\nspeed_kmh = 0\n";
  const fs::path config = dir.path() / "fleetgw.toml";
  const fs::path socket = dir.path() / "status.sock";
  std::ofstream(config) << "[vehicle]\nid = \"tls-bike\"\n[log]\nlevel = \"info\"\n"
                        << "[can]\ntransport = \"sim\"\n[sim]\nscenario = \""
                        << (dir.path() / "quiet.toml").string()
                        << "\"\nspeed = 1\nlockstep = true\n"
                        << "[storage]\npath = \"" << (dir.path() / "fleetgw.db").string()
                        << "\"\n[status]\nsocket = \"" << socket.string() << "\"\n"
                        << "[mqtt]\nenabled = true\nuri = \"" << uri << "\"\nca_file = \""
                        << pki.ca_cert.string() << "\"\nreconnect_min_ms = 100\n"
                        << "reconnect_max_ms = 500\n";
  fleetgw::testing::GatewayProcess gateway(FLEETGW_BINARY, config, {"--duration", "60"});

  const fs::path json_out = dir.path() / "status.json";
  std::string reason;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    fleetgw({"status", "--json", "--socket", socket.string()}, json_out);
    // The document, then (exit 1) the "ATTENTION: ..." line of stderr in the same file.
    const std::string text = read_text_file(json_out);
    const auto last = text.rfind('}');
    const auto doc = nlohmann::json::parse(
        last == std::string::npos ? text : text.substr(0, last + 1), nullptr, false);
    if (doc.is_object() && doc.contains("broker")) {
      reason = doc["broker"].value("last_connect_error", "");
      if (!reason.empty()) break;
    }
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(reason, "TLS: certificate verify failed (certificate has expired)")
      << read_text_file(json_out) << gateway.log();

  const fs::path text_out = dir.path() / "status.txt";
  EXPECT_EQ(fleetgw({"status", "--socket", socket.string()}, text_out), 1)
      << "needs attention\n"
      << read_text_file(text_out);
  EXPECT_NE(read_text_file(text_out).find("expired"), std::string::npos)
      << read_text_file(text_out);
  EXPECT_EQ(gateway.stop(), 0);
  const std::string log = gateway.log();
  EXPECT_NE(log.find("certificate has expired"), std::string::npos) << log;
}

}  // namespace
