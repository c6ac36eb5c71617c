// CPU cost of building one telemetry Envelope of 256 samples from stored sample bytes:
//  * BM_TelemetryEnvelope/generated: the uplink's former path -- parse each stored sample, set
//    its sequence, add it to a TelemetryBatch, serialise the Envelope;
//  * BM_TelemetryEnvelope/spliced: gateway/uplink/envelope_writer.h, which checks the wire
//    format and splices the stored bytes (byte-identical output, see tests/uplink).
// and of one Envelope per record of the other kinds (issue 26), from its stored body:
//  * BM_RecordEnvelope_generated/<kind>: the uplink's former path (serialize_record before
//    issue 26) -- parse the body into the Envelope's field, fill the header, serialise;
//  * BM_RecordEnvelope_spliced/<kind>: serialize_record now -- walk the body's wire format, write
//    the header, splice tag + length + stored body.
// Run: build/bench/bench_envelope
#include <benchmark/benchmark.h>

#include <random>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/outbox_source.h"
#include "gateway/uplink/envelope_writer.h"

namespace {

using namespace fleetgw;

std::vector<std::string> stored_samples() {
  std::mt19937_64 rng(1);
  std::vector<std::string> out;
  for (int i = 0; i < 256; ++i) {
    v1::TelemetrySample s;
    s.set_sampled_at_us(1'700'000'000'000'000 + i * 100'000);
    s.set_speed_dkmh(static_cast<std::uint32_t>(rng() % 300));
    s.set_motor_rpm(static_cast<std::uint32_t>(rng() % 200));
    s.set_power_w(static_cast<std::int32_t>(rng() % 600));
    s.set_voltage_mv(48'000 + static_cast<std::uint32_t>(rng() % 500));
    s.set_current_ma(-static_cast<std::int32_t>(rng() % 9000));
    s.set_cadence_rpm(static_cast<std::uint32_t>(rng() % 90));
    s.set_torque_dnm(static_cast<std::uint32_t>(rng() % 400));
    s.set_assist(2);
    s.set_soc_pct(80);
    s.set_odo_m(123'456'700);
    s.set_motor_temp_c(41);
    out.push_back(s.SerializeAsString());
  }
  return out;
}

const uplink::EnvelopeHeader kHeader{"bike-0001", 1000, 1'700'000'000'000'000, "0.1.0",
                                     "6f1c0a5e-2b7d-4e3a-9c1f-0d8e7b6a5c4d"};

void BM_TelemetryEnvelope_generated(benchmark::State& state) {
  const auto samples = stored_samples();
  std::size_t bytes = 0;
  for (auto _ : state) {
    v1::Envelope env;
    uplink::fill_header(env, kHeader);
    std::uint64_t seq = 1000;
    for (const auto& stored : samples) {
      v1::TelemetrySample s;
      s.ParseFromString(stored);
      s.set_sequence(seq++);
      *env.mutable_telemetry()->add_samples() = std::move(s);
    }
    const std::string out = env.SerializeAsString();
    bytes = out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.SetItemsProcessed(state.iterations() * 256);
}
BENCHMARK(BM_TelemetryEnvelope_generated)->Unit(benchmark::kMicrosecond);

void BM_TelemetryEnvelope_spliced(benchmark::State& state) {
  const auto samples = stored_samples();
  std::size_t bytes = 0;
  for (auto _ : state) {
    uplink::TelemetryBatchWriter writer;
    std::uint64_t seq = 1000;
    for (const auto& stored : samples) {
      // As the uplink does: check and measure (for the batch limits), then splice.
      const auto sample = uplink::TelemetryBatchWriter::prepare(stored, seq++);
      writer.add(*sample);
    }
    const std::string out = writer.take_envelope(kHeader);
    bytes = out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.SetItemsProcessed(state.iterations() * 256);
}
BENCHMARK(BM_TelemetryEnvelope_spliced)->Unit(benchmark::kMicrosecond);

// A realistic stored body of each benchmarked kind (as gateway/domain and the command service
// write them).
std::string stored_body(int kind) {
  switch (kind) {
    case 0: {
      v1::FaultEvent f;
      f.set_node("bms");
      f.set_bit(5);
      f.set_code(0x2105);
      f.set_name("cell over-temperature");
      f.set_severity(v1::FAULT_SEVERITY_CRITICAL);
      f.set_kind(v1::FAULT_EVENT_KIND_RAISED);
      return f.SerializeAsString();
    }
    case 1: {
      v1::RideRecord r;
      r.set_ride_id("ride-1700000000-0001");
      r.set_started_at_us(1'700'000'000'000'000);
      r.set_ended_at_us(1'700'000'180'000'000);
      r.set_duration_ms(1'800'000);
      r.set_moving_time_ms(1'700'000);
      r.set_start_odo_m(123'456'000);
      r.set_end_odo_m(123'465'100);
      r.set_distance_odo_m(9'100);
      r.set_distance_integrated_m(9'080);
      r.set_max_speed_dkmh(251);
      r.set_avg_speed_dkmh(182);
      r.set_energy_mwh(152'000);
      r.set_energy_mah(3'100);
      r.set_soc_start_pct(88);
      return r.SerializeAsString();
    }
    case 2: {
      v1::CommandResult c;
      c.set_command_id("0b9c2c1e-6f1d-4c4e-9d7e-2f5a3b1c0d9e");
      c.set_result(v1::COMMAND_RESULT_CODE_SUCCEEDED);
      c.set_reason("locked");
      c.set_duration_ms(840);
      c.set_final_lock_state_name("locked");
      return c.SerializeAsString();
    }
    default: {
      v1::LockEvent l;
      l.set_lock_kind("wheel");
      l.set_previous_state_name("unlocked");
      l.set_state_name("locked");
      l.set_at_us(1'700'000'000'000'000);
      l.set_command_id("0b9c2c1e-6f1d-4c4e-9d7e-2f5a3b1c0d9e");
      return l.SerializeAsString();
    }
  }
}
const char* const kBenchKinds[] = {uplink::kind::kFault, uplink::kind::kRide,
                                   uplink::kind::kCommandResult, uplink::kind::kLock};

void BM_RecordEnvelope_generated(benchmark::State& state) {
  const std::string body = stored_body(static_cast<int>(state.range(0)));
  const int kind = static_cast<int>(state.range(0));
  for (auto _ : state) {
    v1::Envelope env;
    uplink::fill_header(env, kHeader);
    bool ok = false;
    switch (kind) {
      case 0:
        ok = env.mutable_fault()->ParseFromString(body);
        break;
      case 1:
        ok = env.mutable_ride()->ParseFromString(body);
        break;
      case 2:
        ok = env.mutable_command_result()->ParseFromString(body);
        break;
      default:
        ok = env.mutable_lock()->ParseFromString(body);
        break;
    }
    benchmark::DoNotOptimize(ok);
    const std::string out = env.SerializeAsString();
    benchmark::DoNotOptimize(out.data());
  }
  state.SetLabel(kBenchKinds[kind]);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordEnvelope_generated)->DenseRange(0, 3)->Unit(benchmark::kNanosecond);

void BM_RecordEnvelope_spliced(benchmark::State& state) {
  const int kind = static_cast<int>(state.range(0));
  const std::string body = stored_body(kind);
  const uplink::KindRoute* route = uplink::find_route(kBenchKinds[kind]);
  for (auto _ : state) {
    const auto out = uplink::serialize_record(*route, kHeader, body);
    benchmark::DoNotOptimize(out->data());
  }
  state.SetLabel(kBenchKinds[kind]);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RecordEnvelope_spliced)->DenseRange(0, 3)->Unit(benchmark::kNanosecond);

}  // namespace

BENCHMARK_MAIN();
