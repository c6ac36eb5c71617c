// The cost of building one status of the running service (issue 26, "status is built as its
// protobuf directly"): the fleetgw.v1.Status the uplink publishes retained, and the local JSON
// document the status socket serves (`fleetgw status`). Real components: a GatewayCore, a
// SQLite store in a temporary directory with queued outbox records, an uplink object (not
// started), a failing store and a TLS failure, so every section and every attention rule has
// something to say. Run: <build>/bench/bench_status.
#include <benchmark/benchmark.h>

#include <optional>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/runtime/status_provider.h"
#include "gateway/runtime/store_outbox.h"
#include "tests/support/temp_dir.h"

namespace {

using namespace fleetgw;
using runtime::Micros;

struct RefusingSender final : node::FrameSender {
  bool send(const motinova::AppFrame&) override { return false; }
};

struct IdleBus final : can::Transport {
  IdleBus() { health_.state = can::ControllerState::kUp; }
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame&) override { return false; }
  void stop() override {}
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "idle0"; }
  can::BusHealth health_;
};

class Service {
 public:
  Service() {
    config_.storage.path = (dir_.path() / "fleetgw.db").string();
    config_.storage.max_mb = 64;
    config_.mqtt.enabled = true;
    config_.mqtt.uri = "ssl://127.0.0.1:8883";
    storage::StoreOptions so;
    so.path = config_.storage.path;
    store_.emplace(so);
    storage::Batch batch;
    batch.now_us = kWallNow.count() - 120'000'000;
    for (int i = 0; i < 20; ++i) {
      batch.messages.push_back(storage::UplinkMessage{storage::OutboxKind::kFault, 1,
                                                      storage::Bytes(40, std::uint8_t{7})});
    }
    store_->write(batch);
    uplink::UplinkConfig uc;
    uc.broker_uri = config_.mqtt.uri;
    uc.vehicle_id = config_.vehicle.id;
    uc.firmware_version = "bench";
    uc.tls = uplink::TlsConfig{};
    outbox_.emplace(*store_);
    uplink_.emplace(uc, *outbox_);
    health_.failing = true;
    health_.last_error = "disk full (SQLITE_FULL)";
    health_.failed_writes = 5383;
    health_.failing_since_us = kWallNow.count() - 42'000'000;
    health_.configured_budget_bytes = 64ull << 20;
    health_.effective_budget_bytes = 64ull << 20;
  }

  // As Pipeline::status_inputs() gathers them for every status.
  runtime::StatusInputs inputs() {
    runtime::StatusInputs in{config_,           core_, bus_, *store_, uplink_->stats(), Micros(0),
                             Micros(10'000'000)};
    in.storage_health = health_;
    in.wall_now = kWallNow;
    return in;
  }

 private:
  static constexpr Micros kWallNow{1'790'000'000'000'000};
  testing::TempDir dir_;
  config::Config config_;
  RefusingSender sender_;
  runtime::GatewayCore core_{config_, sender_};
  IdleBus bus_;
  std::optional<storage::Store> store_;
  std::optional<runtime::StoreOutbox> outbox_;
  std::optional<uplink::Uplink> uplink_;
  storage::StorageHealth health_;
};

// The published Status, built directly from the typed values (make_status_message), copied
// into its envelope as the uplink does and serialised. Before issue 26 this was the JSON
// document, read back into the protobuf by key name: 72 us of CPU against this fixture
// (17 us after; Release, 5 repetitions).
void BM_PublishedStatus(benchmark::State& state) {
  Service s;
  for (auto _ : state) {
    const v1::Status status = runtime::make_status_message(s.inputs());
    v1::Envelope env;
    *env.mutable_status() = status;
    benchmark::DoNotOptimize(env.SerializeAsString());
  }
}
BENCHMARK(BM_PublishedStatus);

// The local JSON document the status socket serves.
void BM_StatusDocument(benchmark::State& state) {
  Service s;
  for (auto _ : state) benchmark::DoNotOptimize(runtime::make_status_json(s.inputs()).dump());
}
BENCHMARK(BM_StatusDocument);

}  // namespace

BENCHMARK_MAIN();
