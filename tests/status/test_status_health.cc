// Honest status (issue 11): storage failures, a clamped disk budget and uplink/TLS connect
// failures reach the status document built by the service (runtime::make_status_json), make
// `fleetgw status` say ATTENTION with exit 1 (text and --json), and reach the published
// fleetgw.v1.Status (runtime::make_status_message, built directly from the same typed values,
// issue 26: the two agree on every field they share); a healthy service is OK with exit 0.
#include <gtest/gtest.h>

#include <asio/io_context.hpp>
#include <asio/post.hpp>
#include <chrono>
#include <sstream>
#include <thread>

#include "gateway/runtime/status_provider.h"
#include "gateway/status/status_command.h"
#include "gateway/status/status_server.h"
#include "gateway/uplink/memory_outbox.h"
#include "status_test_util.h"

namespace fleetgw::status {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;
using runtime::Micros;
using test::TempDir;

// Why the uplink cannot connect, as its stats report it.
struct Failure {
  std::string why;
  std::int64_t at_us = 0;
  std::uint64_t tls_failures = 0;
};

struct RefusingSender final : node::FrameSender {
  bool send(const motinova::AppFrame&) override { return false; }
};

// A bus that is up and carries nothing: the status then depends only on what the test injects.
struct IdleBus final : can::Transport {
  IdleBus() { health_.state = can::ControllerState::kUp; }
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame&) override { return false; }
  void stop() override {}
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "idle0"; }
  can::BusHealth health_;
};

// The real provider over real components: a GatewayCore, a SQLite store in a temp dir and an
// uplink (not started). Nodes are expected online on a real bike, so the test marks the
// document's nodes online: only storage and uplink health are under test here.
class ServiceStatus : public ::testing::Test {
 protected:
  ServiceStatus() {
    config_.storage.path = (dir_.path() / "fleetgw.db").string();
    config_.storage.max_mb = 64;
    config_.mqtt.enabled = true;
    config_.mqtt.uri = "ssl://127.0.0.1:8883";
    storage::StoreOptions so;
    so.path = config_.storage.path;
    store_.emplace(so);
    uplink::UplinkConfig uc;
    uc.broker_uri = "ssl://127.0.0.1:8883";
    uc.vehicle_id = config_.vehicle.id;
    uc.tls = uplink::TlsConfig{};
    uplink_.emplace(uc, outbox_);
  }

  runtime::StatusInputs inputs(std::optional<storage::StorageHealth> health,
                               std::optional<Failure> failure, bool with_uplink = true) {
    runtime::StatusInputs in{config_, core_, bus_, *store_, std::nullopt, Micros(0),
                             Micros(10'000'000)};
    if (with_uplink) {
      in.uplink = uplink_->stats();
      if (failure) {
        in.uplink->last_connect_error = failure->why;
        in.uplink->last_connect_error_us = failure->at_us;
        in.uplink->tls_failures = failure->tls_failures;
      }
    }
    in.storage_health = std::move(health);
    in.wall_now = kWallNow;
    in.revocation_version = revocation_version_;
    return in;
  }

  json document(std::optional<storage::StorageHealth> health, std::optional<Failure> failure,
                bool with_uplink = true) {
    json d = runtime::make_status_json(inputs(std::move(health), std::move(failure), with_uplink));
    for (auto& n : d["nodes"]) n["online"] = true;
    return d;
  }

  static constexpr Micros kWallNow{1'790'000'000'000'000};
  TempDir dir_;
  config::Config config_;
  RefusingSender sender_;
  runtime::GatewayCore core_{config_, sender_};
  IdleBus bus_;
  std::optional<storage::Store> store_;
  uplink::MemoryOutbox outbox_;
  std::optional<uplink::Uplink> uplink_;
  std::optional<std::uint64_t> revocation_version_;  // nullopt: no [command.root_keys]
};

storage::StorageHealth disk_full() {
  storage::StorageHealth h;
  h.failing = true;
  h.last_error = "disk full (SQLITE_FULL)";
  h.failed_writes = 5383;
  h.failing_since_us = 1'790'000'000'000'000 - 42'000'000;  // 42 s before kWallNow
  h.configured_budget_bytes = 64ull << 20;
  h.effective_budget_bytes = 64ull << 20;
  h.dropped_records = 17;
  return h;
}

std::vector<std::string> rules_of(const json& doc) {
  std::vector<std::string> out;
  for (const auto& f : evaluate(doc)) out.push_back(f.rule);
  return out;
}

TEST_F(ServiceStatus, HealthyStorageAndNoUplinkIsOk) {
  storage::StorageHealth ok;
  ok.configured_budget_bytes = ok.effective_budget_bytes = 64ull << 20;
  const json d = document(ok, std::nullopt, /*with_uplink=*/false);
  EXPECT_TRUE(evaluate(d).empty()) << d.dump(2);
  EXPECT_EQ(d["storage"]["failing"], false);
  EXPECT_EQ(d["storage"]["failing_for_s"], nullptr);
}

TEST_F(ServiceStatus, FailingStorageNeedsAttentionWithReasonCountAndAge) {
  const json d = document(disk_full(), std::nullopt, /*with_uplink=*/false);
  EXPECT_EQ(d["storage"]["failed_writes"], 5383);
  EXPECT_DOUBLE_EQ(d["storage"]["failing_for_s"].get<double>(), 42.0);
  EXPECT_EQ(d["storage"]["dropped_records"], 17);
  const auto f = evaluate(d);
  ASSERT_EQ(f.size(), 1u) << d.dump(2);
  EXPECT_EQ(f[0].rule, "storage");
  EXPECT_NE(f[0].detail.find("disk full (SQLITE_FULL)"), std::string::npos) << f[0].detail;
  EXPECT_NE(f[0].detail.find("5383 failed writes"), std::string::npos) << f[0].detail;
  EXPECT_NE(f[0].detail.find("42.0 s"), std::string::npos) << f[0].detail;
  const std::string text = format_summary(d, f);
  EXPECT_NE(text.find("WRITES FAILING"), std::string::npos) << text;
  EXPECT_NE(text.find("dropped records 17"), std::string::npos) << text;
}

TEST_F(ServiceStatus, ClampedBudgetNeedsAttentionAndIsTheBudgetShown) {
  storage::StorageHealth h;
  h.configured_budget_bytes = 64ull << 20;
  h.effective_budget_bytes = 10ull << 20;
  const json d = document(h, std::nullopt, /*with_uplink=*/false);
  EXPECT_EQ(d["disk"]["budget_bytes"], 10ull << 20);
  EXPECT_EQ(rules_of(d), std::vector<std::string>{"budget"});
  EXPECT_NE(format_summary(d, evaluate(d)).find("budget clamped to 10.0 MiB"), std::string::npos);
}

TEST_F(ServiceStatus, TlsFailureIsTheBrokerFindingsReason) {
  Failure tls{
      "TLS: certificate verify failed (unable to get local issuer "
      "certificate)",
      kWallNow.count() - 3'000'000, 4};
  const json d = document(std::nullopt, tls);
  EXPECT_EQ(d["broker"]["tls_failures"], 4);
  EXPECT_DOUBLE_EQ(d["broker"]["last_connect_error_age_s"].get<double>(), 3.0);
  const auto f = evaluate(d);
  ASSERT_EQ(f.size(), 1u) << d.dump(2);
  EXPECT_EQ(f[0].rule, "broker");
  EXPECT_NE(f[0].detail.find("certificate verify failed"), std::string::npos) << f[0].detail;
  EXPECT_NE(format_summary(d, f).find("TLS failures 4"), std::string::npos);
}

TEST_F(ServiceStatus, PublishedStatusCarriesTheSameHealthAndVerdict) {
  Failure tls{"TLS: host name mismatch", kWallNow.count() - 1'000'000, 1};
  const v1::Status s = runtime::make_status_message(inputs(disk_full(), tls));
  EXPECT_TRUE(s.storage().failing());
  EXPECT_EQ(s.storage().last_error(), "disk full (SQLITE_FULL)");
  EXPECT_EQ(s.storage().failed_writes(), 5383u);
  EXPECT_EQ(s.storage().failing_since_us(), kWallNow.count() - 42'000'000);
  EXPECT_EQ(s.storage().dropped_records(), 17u);
  EXPECT_EQ(s.last_connect_error(), "TLS: host name mismatch");
  EXPECT_EQ(s.last_connect_error_at_us(), kWallNow.count() - 1'000'000);
  EXPECT_EQ(s.tls_failures(), 1u);
  EXPECT_TRUE(s.attention_needed());
  // Every expected node was never heard (a bare core), then the broker and the store.
  const auto nodes = document(std::nullopt, std::nullopt)["nodes"].size();
  ASSERT_EQ(static_cast<std::size_t>(s.attention_size()), nodes + 2);
  EXPECT_NE(s.attention(nodes).find("host name mismatch"), std::string::npos);
  EXPECT_NE(s.attention(nodes + 1).find("store writes failing for 42.0 s"), std::string::npos);
  // A compatible addition: an old reader skips the fields, a new one reads them back.
  v1::Status back;
  ASSERT_TRUE(back.ParseFromString(s.SerializeAsString()));
  EXPECT_EQ(back.storage().failed_writes(), 5383u);
}

// Issue 26: the Status is built from the typed values, not read back from the document; both
// must still say the same thing. A populated status (failing store, clamped budget, TLS failure,
// MQTT 5 refusals, queued records, offline nodes): every field the Status shares with the
// document has the document's value, and its verdict is `fleetgw status`'s, line for line.
TEST_F(ServiceStatus, PublishedStatusAndDocumentAgreeOnEveryField) {
  storage::Batch batch;
  batch.now_us = 4'000'000;  // 6 s before the status's `now`
  for (int i = 0; i < 3; ++i) {
    batch.messages.push_back(
        storage::UplinkMessage{storage::OutboxKind::kFault, 1, storage::Bytes(8, 1)});
  }
  ASSERT_TRUE(store_->write(batch).ok());
  storage::StorageHealth h = disk_full();
  h.effective_budget_bytes = 10ull << 20;  // clamped
  runtime::StatusInputs in =
      inputs(h, Failure{"TLS: certificate verify failed", kWallNow.count() - 3'000'000, 2});
  in.uplink->outbox_depth = 3;
  in.uplink->oldest_unsent_created_us = 4'000'000;
  in.uplink->last_publish_ok_us = kWallNow.count() - 9'000'000;
  in.uplink->publish_refusals = 4;
  in.uplink->last_publish_refusal = "0x87 Not authorized (fleet/v1/bike-0001/ride)";
  in.uplink->last_publish_refusal_code = 0x87;
  in.uplink->last_publish_refusal_us = kWallNow.count() - 5'000'000;
  in.uplink->refused_records = 2;
  in.bus_state = v1::BUS_STATE_ACTIVE;

  const json d = runtime::make_status_json(in);
  const v1::Status s = runtime::make_status_message(in);
  const json& st = d["storage"];
  EXPECT_EQ(s.storage().failing(), st["failing"].get<bool>());
  EXPECT_EQ(s.storage().last_error(), st["last_error"].get<std::string>());
  EXPECT_EQ(s.storage().failed_writes(), st["failed_writes"].get<std::uint64_t>());
  EXPECT_EQ(s.storage().failing_since_us(), st["failing_since_us"].get<std::int64_t>());
  EXPECT_EQ(s.storage().configured_budget_bytes(),
            st["configured_budget_bytes"].get<std::uint64_t>());
  EXPECT_EQ(s.storage().effective_budget_bytes(),
            st["effective_budget_bytes"].get<std::uint64_t>());
  EXPECT_EQ(s.storage().effective_budget_bytes(), d["disk"]["budget_bytes"].get<std::uint64_t>());
  EXPECT_EQ(s.storage().dropped_records(), st["dropped_records"].get<std::uint64_t>());
  const json& b = d["broker"];
  EXPECT_EQ(s.last_connect_error(), b["last_connect_error"].get<std::string>());
  EXPECT_EQ(s.last_connect_error_at_us(), b["last_connect_error_us"].get<std::int64_t>());
  EXPECT_EQ(s.tls_failures(), b["tls_failures"].get<std::uint64_t>());
  EXPECT_EQ(s.last_publish_ok_at_us(), b["last_publish_ok_us"].get<std::int64_t>());
  EXPECT_EQ(s.publish_refusals(), b["publish_refusals"].get<std::uint64_t>());
  EXPECT_EQ(s.last_publish_refusal(), b["last_publish_refusal"].get<std::string>());
  EXPECT_EQ(s.last_publish_refusal_code(), b["last_publish_refusal_code"].get<std::uint32_t>());
  EXPECT_EQ(s.last_publish_refusal_at_us(), b["last_publish_refusal_us"].get<std::int64_t>());
  EXPECT_EQ(s.outbox_depth(), d["outbox"]["depth"].get<std::uint64_t>());
  EXPECT_EQ(s.outbox_depth(), 3u);
  // The document shows the age on the service's (bus) clock: 10 s - 4 s.
  EXPECT_DOUBLE_EQ(d["outbox"]["oldest_unsent_age_s"].get<double>(), 6.0);
  EXPECT_EQ(s.oldest_unsent_created_at_us(), 4'000'000);
  EXPECT_EQ(s.firmware_version(), d["version"].get<std::string>());
  EXPECT_EQ(s.bus_state(), v1::BUS_STATE_ACTIVE);

  // The verdict: what `fleetgw status` finds in the document is what the Status says.
  const auto findings = evaluate(d);
  ASSERT_EQ(static_cast<std::size_t>(s.attention_size()), findings.size()) << d.dump(2);
  for (std::size_t i = 0; i < findings.size(); ++i) {
    EXPECT_EQ(s.attention(static_cast<int>(i)), findings[i].detail);
  }
  EXPECT_TRUE(s.attention_needed());
  std::vector<std::string> rules;
  for (const auto& f : findings) rules.push_back(f.rule);
  std::vector<std::string> want(d["nodes"].size(), "node");  // none heard: a bare core
  want.insert(want.end(), {"broker", "broker", "storage", "budget"});
  EXPECT_EQ(rules, want) << d.dump(2);

  // A healthy one has no verdict in either form.
  in.storage_health = storage::StorageHealth{};
  in.uplink.reset();
  const v1::Status quiet = runtime::make_status_message(in);
  EXPECT_EQ(static_cast<std::size_t>(quiet.attention_size()), d["nodes"].size())
      << "only the never-heard nodes";
  EXPECT_FALSE(quiet.storage().failing());
}

// `fleetgw status` against a status socket serving the provider's document.
struct Served {
  int code;
  std::string out, err;
};

Served serve_and_query(const std::filesystem::path& sock, const json& doc, bool json_out) {
  asio::io_context io;
  StatusServer server(io, sock, [&] { return doc; });
  std::thread loop([&] { io.run(); });
  StatusCommandOptions o;
  o.socket_path = sock.string();
  o.json = json_out;
  std::ostringstream out, err;
  const int code = run_status_command(o, out, err);
  asio::post(io, [&] { server.stop(); });
  loop.join();
  return {code, out.str(), err.str()};
}

TEST_F(ServiceStatus, StatusCommandExitsOneOnFailuresAndZeroWhenHealthy) {
  const auto sock = dir_.path() / "status.sock";
  Failure tls{"TLS: certificate verify failed (certificate has expired)",
                             kWallNow.count() - 1'000'000, 2};
  const json bad = document(disk_full(), tls);
  const Served text = serve_and_query(sock, bad, false);
  EXPECT_EQ(text.code, kStatusAttention) << text.err;
  EXPECT_NE(text.out.find("ATTENTION: store writes failing for 42.0 s: disk full"),
            std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("certificate has expired"), std::string::npos) << text.out;
  const Served js = serve_and_query(sock, bad, true);
  EXPECT_EQ(js.code, kStatusAttention);
  EXPECT_EQ(json::parse(js.out)["storage"]["last_error"], "disk full (SQLITE_FULL)");
  EXPECT_NE(js.err.find("ATTENTION: store writes failing"), std::string::npos) << js.err;

  storage::StorageHealth ok;
  ok.configured_budget_bytes = ok.effective_budget_bytes = 64ull << 20;
  const Served good = serve_and_query(sock, document(ok, std::nullopt, false), false);
  EXPECT_EQ(good.code, kStatusOk) << good.out;
  EXPECT_NE(good.out.find("\nOK\n"), std::string::npos) << good.out;
}

// Issue 28: the technician sees which revocation list the gateway enforces (a revoked console
// key still accepted means an old list), in --json and in the text summary alike.
TEST_F(ServiceStatus, StatusShowsTheRevocationListVersionInForce) {
  const auto sock = dir_.path() / "status.sock";
  revocation_version_ = 4;
  const json d = document(std::nullopt, std::nullopt, /*with_uplink=*/false);
  ASSERT_TRUE(d.contains("revocations")) << d.dump(2);
  EXPECT_EQ(d["revocations"]["version"], 4) << d.dump(2);
  const Served js = serve_and_query(sock, d, true);
  EXPECT_EQ(json::parse(js.out)["revocations"]["version"], 4) << js.out;
  const Served text = serve_and_query(sock, d, false);
  EXPECT_NE(text.out.find("revocation list version 4 in force"), std::string::npos) << text.out;

  revocation_version_ = 0;  // roots configured, no list received yet
  const json none = document(std::nullopt, std::nullopt, /*with_uplink=*/false);
  ASSERT_TRUE(none.contains("revocations")) << none.dump(2);
  EXPECT_EQ(none["revocations"]["version"], nullptr) << none.dump(2);
  EXPECT_NE(format_summary(none, evaluate(none)).find("no revocation list in force"),
            std::string::npos);

  revocation_version_.reset();  // no [command.root_keys]: no section
  EXPECT_FALSE(document(std::nullopt, std::nullopt, false).contains("revocations"));
}

}  // namespace
}  // namespace fleetgw::status
