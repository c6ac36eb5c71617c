// Command round trip through the SHIPPED service: `fleetgw run` as a child process on the
// simulated bike, a real mosquitto (set_tcp_nodelay, as deploy/ configures it), and an operator
// in this process that signs each command (Ed25519), publishes it on <prefix>/<V>/cmd and waits
// for the CommandResult bound to its id on cmd/result. The lock confirms at once: "lock" sent to
// the simulated seat lock that is already locked is confirmed by its next status broadcast
// (3-20 ms of bus time; the simulator runs at speed 20, so 0.15-1 ms of wall time).
//
//   build/bench/bench_service                       # 1,000 commands: median, p99, max
//   build/bench/bench_service --benchmark_filter=x  # (Google Benchmark flags)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>

#include "tests/runtime/service_process.h"
#include "tests/support/mosquitto_fixture.h"

namespace {

using namespace std::chrono_literals;

void BM_ServiceCommandRoundTrip(benchmark::State& state) {
  fleetgw::testing::TempDir dir("fleetgw-bench-svc");
  fleetgw::testing::MosquittoBroker broker;
  broker.start();
  auto key = fleetgw::command::Ed25519PrivateKey::generate();
  fleetgw::testing::ServiceConfigText c;
  c.scenario = std::filesystem::path(FLEETGW_SOURCE_DIR) / "config/scenarios/parked.toml";
  // SIM_SPEED overrides: the simulated lock's own reply time is bus time / speed.
  c.speed = std::getenv("SIM_SPEED") ? std::atof(std::getenv("SIM_SPEED")) : 20.0;
  c.db = dir.path() / "fleetgw.db";
  c.broker_uri = broker.uri();
  c.vehicle = "bench-svc";
  c.key_id = "ops";
  c.public_key_b64 = key.public_key().base64();
  // A 600 s parked scenario at speed 20 lasts 30 s of wall time; repeat it as needed.
  std::ofstream(dir.path() / "fleetgw.toml") << c.text();
  fleetgw::testing::ServiceProcess service(FLEETGW_BIN, dir.path() / "fleetgw.toml",
                                           dir.path() / "service.log");
  if (!fleetgw::testing::wait_for_text(dir.path() / "service.log", "uplink: connected", 30s)) {
    state.SkipWithError("the service did not connect");
    return;
  }
  std::this_thread::sleep_for(1500ms);
  fleetgw::testing::CommandOperator op(broker.uri(), "bench-svc", std::move(key), "ops");
  std::vector<double> us;
  std::size_t failures = 0;
  int i = 0;
  for (auto _ : state) {
    const auto o = op.send("svc-" + std::to_string(i++), "seat", "lock", 10s);
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
BENCHMARK(BM_ServiceCommandRoundTrip)
    ->Iterations(1000)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
