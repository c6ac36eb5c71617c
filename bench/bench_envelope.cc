// CPU cost of building one telemetry Envelope of 256 samples from stored sample bytes:
//  * BM_TelemetryEnvelope/generated: the uplink's former path -- parse each stored sample, set
//    its sequence, add it to a TelemetryBatch, serialise the Envelope;
//  * BM_TelemetryEnvelope/spliced: gateway/uplink/envelope_writer.h, which checks the wire
//    format and splices the stored bytes (byte-identical output, see tests/uplink).
// Run: build/bench/bench_envelope
#include <benchmark/benchmark.h>

#include <random>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
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

}  // namespace

BENCHMARK_MAIN();
