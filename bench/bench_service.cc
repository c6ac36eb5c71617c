// Command round trip through the SHIPPED service: `fleetgw run` as a child process on the
// simulated bike, a real mosquitto (set_tcp_nodelay, as deploy/ configures it), and an operator
// in this process that signs each command (Ed25519), publishes it on <prefix>/<V>/cmd and waits
// for the CommandResult bound to its id on cmd/result. The lock confirms at once: "lock" sent to
// the simulated seat lock that is already locked is confirmed by its next status broadcast
// (3-20 ms of bus time; the simulator runs at speed 20, so 0.15-1 ms of wall time).
//
// BM_ServiceSpeedLimitRoundTrip (issue 13): the same path for a speed-limit command, which the
// gateway confirms from the bus: read the MC settings (0x3300 -> 0x5408), write the limit
// (0x3408), read back; the limit alternates 15 / 20 km/h so every command really changes it.
//
//   build/bench/bench_service                       # both: median, p99, max
//   build/bench/bench_service --benchmark_filter=x  # (Google Benchmark flags)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <optional>

#include "tests/runtime/service_process.h"
#include "tests/support/gateway_config.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/support/wait.h"

namespace {

using namespace std::chrono_literals;

// One `fleetgw run` on the parked simulated bike with a real mosquitto, and its operator.
class ServiceRig {
 public:
  ServiceRig() {
    broker_.start();
    auto key = fleetgw::command::Ed25519PrivateKey::generate();
    // SIM_SPEED overrides: the simulated nodes' own reply times are bus time / speed.
    const double speed = std::getenv("SIM_SPEED") ? std::atof(std::getenv("SIM_SPEED")) : 20.0;
    // A 600 s parked scenario at speed 20 lasts 30 s of wall time; repeat it as needed.
    fleetgw::testing::service_config(
        "bench-svc", dir_.path(),
        std::filesystem::path(FLEETGW_SOURCE_DIR) / "config/scenarios/parked.toml", speed,
        broker_.uri(), "ops", key.public_key().base64())
        .write(dir_.path() / "fleetgw.toml");
    service_.emplace(FLEETGW_BIN, dir_.path() / "fleetgw.toml", dir_.path() / "service.log");
    ready_ = fleetgw::testing::wait_until(
        [&] { return service_->log_contains("uplink: connected"); }, 30s);
    // The MC has answered its first polls (settings included) before the first command.
    std::this_thread::sleep_for(1500ms);
    op_.emplace(broker_.uri(), "bench-svc", std::move(key), "ops");
  }
  bool ready() const { return ready_; }
  fleetgw::testing::CommandOperator& op() { return *op_; }

 private:
  fleetgw::testing::TempDir dir_{"fleetgw-bench-svc"};
  fleetgw::testing::MosquittoBroker broker_;
  std::optional<fleetgw::testing::ServiceProcess> service_;
  std::optional<fleetgw::testing::CommandOperator> op_;
  bool ready_ = false;
};

// Runs `send(i)` once per iteration; reports median, p99 and max round trip, and how many
// commands did not succeed.
template <class Send>
void round_trips(benchmark::State& state, Send send) {
  ServiceRig rig;
  if (!rig.ready()) {
    state.SkipWithError("the service did not connect");
    return;
  }
  std::vector<double> us;
  std::size_t failures = 0;
  int i = 0;
  for (auto _ : state) {
    const auto o = send(rig.op(), i++);
    us.push_back(static_cast<double>(o.round_trip.count()));
    if (!o.answered || o.result != fleetgw::v1::COMMAND_RESULT_CODE_SUCCEEDED) ++failures;
  }
  std::sort(us.begin(), us.end());
  if (us.empty()) return;
  state.counters["median_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[std::min(us.size() - 1, us.size() * 99 / 100)];
  state.counters["max_us"] = us.back();
  state.counters["not_succeeded"] = static_cast<double>(failures);
}

void BM_ServiceCommandRoundTrip(benchmark::State& state) {
  round_trips(state, [](fleetgw::testing::CommandOperator& op, int i) {
    return op.send("svc-" + std::to_string(i), "seat", "lock", 10s);
  });
}
void BM_ServiceSpeedLimitRoundTrip(benchmark::State& state) {
  round_trips(state, [](fleetgw::testing::CommandOperator& op, int i) {
    return op.send_mc("limit-" + std::to_string(i), "speed_limit", i % 2 == 0 ? "15" : "20", 10s);
  });
}
BENCHMARK(BM_ServiceCommandRoundTrip)
    ->Iterations(1000)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
BENCHMARK(BM_ServiceSpeedLimitRoundTrip)
    ->Iterations(200)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
