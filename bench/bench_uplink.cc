// Uplink throughput and latency against a real local mosquitto (started here via the test
// fixture): backlog drain rate with telemetry batching and without (one MQTT message per
// record), bytes per record on the wire, and record-available-to-PUBACK latency of a live
// record. Run: <build>/bench/bench_uplink (add --benchmark_min_time=... as needed).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"

namespace {

using namespace fleetgw::uplink;
using Clock = std::chrono::steady_clock;

Micros wall_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
}

// A realistic sample: the values one MC running-data message carries.
std::string sample(std::uint32_t i) {
  fleetgw::v1::TelemetrySample s;
  s.set_sampled_at_us(wall_now().count());
  s.set_speed_dkmh(150 + i % 100);
  s.set_motor_rpm(180 + i % 50);
  s.set_power_w(250);
  s.set_voltage_mv(48'100);
  s.set_current_ma(5'200);
  s.set_cadence_rpm(70);
  s.set_torque_dnm(180);
  s.set_assist(2);
  s.set_soc_pct(80);
  s.set_odo_m(1'234'500 + i);
  return s.SerializeAsString();
}

std::string fault(std::uint32_t i) {
  fleetgw::v1::FaultEvent f;
  f.set_node("mc");
  f.set_bit(i % 32);
  f.set_name("over_current_protect");
  f.set_severity(fleetgw::v1::FAULT_SEVERITY_CRITICAL);
  f.set_kind(fleetgw::v1::FAULT_EVENT_KIND_RAISED);
  f.set_occurrences(1);
  return f.SerializeAsString();
}

fleetgw::testing::MosquittoBroker& broker() {
  static fleetgw::testing::MosquittoBroker b;  // one broker for the whole benchmark run
  if (!b.running()) b.start();
  return b;
}

UplinkConfig config(const std::string& vehicle) {
  UplinkConfig c;
  c.broker_uri = broker().uri();
  c.vehicle_id = vehicle;
  c.firmware_version = "0.1.0";
  c.live_telemetry_qos = 1;  // measure the no-loss path
  return c;
}

void drain_until_empty(Uplink& up, MemoryOutbox& box) {
  while (box.stats().depth != 0) {
    up.poll(wall_now());
    up.wait_for_events(std::chrono::milliseconds(1));
  }
}

void connect(Uplink& up) {
  up.start(wall_now());
  while (up.state() != UplinkState::kConnected) {
    up.poll(wall_now());
    up.wait_for_events(std::chrono::milliseconds(5));
  }
}

// Backlog of `records` records (after an outage, say) drained as fast as the broker acks.
void BM_BacklogDrain(benchmark::State& state, bool telemetry) {
  const auto records = static_cast<std::uint32_t>(state.range(0));
  MemoryOutbox box;
  auto cfg = config(telemetry ? "bench-telemetry" : "bench-fault");
  cfg.max_in_flight = static_cast<std::size_t>(state.range(1));
  Uplink up(cfg, box);
  connect(up);
  std::uint64_t drained = 0;
  const auto before = up.stats();
  for (auto _ : state) {
    state.PauseTiming();
    for (std::uint32_t i = 0; i < records; ++i) {
      box.push(telemetry ? 5 : 1, telemetry ? kind::kTelemetry : kind::kFault,
               wall_now().count() - 60'000'000, telemetry ? sample(i) : fault(i));
    }
    state.ResumeTiming();
    drain_until_empty(up, box);
    drained += records;
  }
  const auto after = up.stats();
  state.counters["records_per_s"] =
      benchmark::Counter(static_cast<double>(drained), benchmark::Counter::kIsRate);
  state.counters["bytes_per_record"] =
      static_cast<double>(after.bytes_published - before.bytes_published) /
      static_cast<double>(after.published_records - before.published_records);
  state.counters["msgs_per_s"] =
      benchmark::Counter(static_cast<double>(after.published_messages - before.published_messages),
                         benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_BacklogDrain, telemetry_batched, true)
    ->Args({100'000, 64})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_BacklogDrain, fault_unbatched, false)
    ->Args({20'000, 64})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// One record becomes available (pushed, uplink poked as the runtime would); time until its
// PUBACK has been processed and the outbox acked it.
void BM_LiveRecordToPuback(benchmark::State& state) {
  MemoryOutbox box;
  Uplink up(config("bench-latency"), box);
  connect(up);
  std::vector<double> us;
  std::uint32_t i = 0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    box.push(1, kind::kFault, wall_now().count(), fault(i++));
    drain_until_empty(up, box);
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  }
  std::sort(us.begin(), us.end());
  state.counters["median_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[std::min(us.size() - 1, us.size() * 99 / 100)];
}
BENCHMARK(BM_LiveRecordToPuback)->Iterations(3000)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
