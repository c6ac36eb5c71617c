// Reassembly + CRC + decode throughput over a realistic mix of bus traffic.
//
// Target (issue #2): >= 2 million CAN frames per second on one core, no heap allocation per
// frame in steady state. The allocation count is measured by replacing the global operator new
// in this benchmark program only, and reported as the counter `allocs_per_frame`.
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "motinova/codec.h"
#include "motinova/crc32.h"
#include "motinova/frame.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"

namespace {
std::atomic<uint64_t> g_allocations{0};
}

// GCC cannot see that the replacement operator new below pairs with this operator delete.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace {

using namespace motinova;

AppFrame frame(uint16_t id, uint8_t function, std::size_t n, uint8_t fill) {
  AppFrame f;
  f.can_id = id;
  f.mode = Mode::kReport;
  f.function = function;
  f.data.resize(n);
  for (std::size_t i = 0; i < n; ++i) f.data[i] = static_cast<uint8_t>(fill + i);
  return f;
}

// One second of a riding bike, roughly as the simulator produces it: MC running data and
// fault word at 5 Hz, BMS status/cells/alarms, lock status, OBC faults, model info now and then.
std::vector<CanFrame> traffic_mix() {
  std::vector<AppFrame> messages;
  for (int tick = 0; tick < 5; ++tick) {
    messages.push_back(frame(0x710, 0x10, 32, 7));  // mc_status
    messages.push_back(frame(0x710, 0x11, 4, 0));   // mc_faults
    messages.push_back(frame(0x720, 0x12, 4, 0));   // bms alarms
    messages.push_back(frame(0x730, 0x15, 4, 0));   // obc faults
  }
  messages.push_back(frame(0x720, 0x10, 16, 3));  // bms_status
  messages.push_back(frame(0x720, 0x11, 32, 9));  // bms_cells
  messages.push_back(frame(0x710, 0x15, 16, 1));  // mc_odometer
  for (uint16_t id : {0x770, 0x780, 0x790, 0x7A0, 0x7B0}) {
    messages.push_back(frame(id, 0x10, 16, 2));  // lock_status
    messages.push_back(frame(id, 0x11, 4, 0));   // lock faults
  }
  messages.push_back(frame(0x720, 0x15, 64, 0x41));  // BMS model info
  std::vector<CanFrame> frames;
  for (const auto& m : messages) {
    for (const auto& c : segment(m)) frames.push_back(c);
  }
  return frames;
}

struct DecodingSink : FrameSink {
  const DecodeOptions* options;
  DecodedMessage decoded;
  uint64_t messages = 0;
  double checksum = 0;
  void on_frame(const AppFrame& f, Micros) override {
    decode(f, Catalogue::standard(), *options, decoded);
    ++messages;
    if (decoded.values().size() > 0) checksum += decoded.values()[0].value;
  }
  void on_error(const ReassemblyErrorEvent&) override {}
};

void BM_ReassembleDecodeMix(benchmark::State& state) {
  const auto frames = traffic_mix();
  const DecodeOptions options;
  Reassembler reassembler;
  DecodingSink sink;
  sink.options = &options;
  (void)Catalogue::standard();
  Micros now{0};
  // Warm up, then count allocations only in the measured loop.
  for (const auto& f : frames) reassembler.push(f, now, sink);
  const uint64_t allocs_before = g_allocations.load();
  uint64_t pushed = 0;
  for (auto _ : state) {
    for (const auto& f : frames) {
      now += Micros(400);
      reassembler.push(f, now, sink);
    }
    pushed += frames.size();
  }
  const uint64_t allocs = g_allocations.load() - allocs_before;
  benchmark::DoNotOptimize(sink.checksum);
  state.SetItemsProcessed(static_cast<int64_t>(pushed));
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(pushed), benchmark::Counter::kIsRate);
  state.counters["allocs_per_frame"] = static_cast<double>(allocs) / static_cast<double>(pushed);
  state.counters["messages"] = static_cast<double>(sink.messages);
  if (reassembler.stats().total_errors() != 0) state.SkipWithError("reassembly errors in mix");
}
BENCHMARK(BM_ReassembleDecodeMix);

void BM_ReassembleOnly(benchmark::State& state) {
  const auto frames = traffic_mix();
  Reassembler reassembler;
  struct NullSink : FrameSink {
    uint64_t n = 0;
    void on_frame(const AppFrame&, Micros) override { ++n; }
    void on_error(const ReassemblyErrorEvent&) override {}
  } sink;
  Micros now{0};
  uint64_t pushed = 0;
  for (auto _ : state) {
    for (const auto& f : frames) reassembler.push(f, now += Micros(400), sink);
    pushed += frames.size();
  }
  state.SetItemsProcessed(static_cast<int64_t>(pushed));
}
BENCHMARK(BM_ReassembleOnly);

void BM_Crc32(benchmark::State& state) {
  std::vector<uint8_t> data(static_cast<std::size_t>(state.range(0)), 0x5A);
  for (auto _ : state) benchmark::DoNotOptimize(frame_crc(0x710, data));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * state.range(0)));
}
BENCHMARK(BM_Crc32)->Arg(38)->Arg(264);

}  // namespace

BENCHMARK_MAIN();
