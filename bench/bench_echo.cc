// The cost of one message the gateway transmits, as far as the listeners see it (issue 26,
// "own frames encoded then decoded"): the node's send through node::TransportSender (encode,
// CRC, segments to the transport) and GatewayCore showing it to the listeners after the call
// (deliver_echoes). BM_TransmittedMessage is that whole road per message; BM_EncodeForTheBus
// the bus part alone; BM_DecodeOwnMessage what decoding the message again costs (the part the
// echoes no longer pay).
//
//   build-rel/bench/bench_echo --benchmark_min_time=1   (Release; CPU time per message: the
//   counter ns_per_message)
#include <benchmark/benchmark.h>

#include <cstdint>
#include <string_view>

#include "gateway/can/transport.h"
#include "gateway/config/config.h"
#include "gateway/node/messages.h"
#include "gateway/node/transport_sender.h"
#include "gateway/runtime/gateway_core.h"
#include "motinova/codec.h"

namespace {

using namespace fleetgw;
using motinova::Micros;

// Accepts every CAN frame, as an idle SocketCAN queue does.
class NullTransport final : public can::Transport {
 public:
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame&) override {
    ++health_.tx_frames;
    return true;
  }
  void stop() override {}
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "null"; }

 private:
  can::BusHealth health_;
};

// Reads what a tracker reads: the message's name and a field.
class Reader final : public runtime::MessageListener {
 public:
  void on_message(const motinova::DecodedMessage& m, Micros) override {
    seen += m.name().size() + m.values().size();
  }
  std::uint64_t seen = 0;
};

config::Config bench_config() {
  return config::parse_config("[log]\nlevel = \"warn\"\n", "bench.toml");
}

void BM_TransmittedMessage(benchmark::State& state) {
  const auto config = bench_config();
  NullTransport transport;
  node::TransportSender sender(transport, config.protocol.crc_order);
  runtime::GatewayCore core(config, sender);
  Reader trackers, commands, campaigns;
  core.add_listener(trackers);
  core.add_listener(commands);
  core.add_listener(campaigns);
  Micros t{1'717'228'800'000'000};
  core.start(t);
  for (auto _ : state) {
    // Two messages per iteration: the gateway's LOCK and UNLOCK broadcasts (0x760), each shown
    // to the listeners after the call that sent it, as the command service's are.
    core.node().vehicle_lock(t);
    core.deliver_echoes();
    core.node().vehicle_unlock(t);
    core.deliver_echoes();
    t += Micros(1000);
  }
  benchmark::DoNotOptimize(trackers.seen);
  state.SetItemsProcessed(state.iterations() * 2);
  state.counters["ns_per_message"] =
      benchmark::Counter(static_cast<double>(state.iterations() * 2),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_TransmittedMessage);

void BM_EncodeForTheBus(benchmark::State& state) {
  const auto config = bench_config();
  NullTransport transport;
  node::TransportSender sender(transport, config.protocol.crc_order);
  const auto lock = node::keyword_frame(node::ids::kIotBroadcast, motinova::Mode::kReport,
                                        node::fn::kIotLock, node::keyword::kLock);
  for (auto _ : state) benchmark::DoNotOptimize(sender.send(lock));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_EncodeForTheBus);

void BM_DecodeOwnMessage(benchmark::State& state) {
  const auto config = bench_config();
  const auto lock = node::keyword_frame(node::ids::kIotBroadcast, motinova::Mode::kReport,
                                        node::fn::kIotLock, node::keyword::kLock);
  motinova::DecodedMessage decoded;
  for (auto _ : state) {
    motinova::decode(lock, motinova::Catalogue::standard(), config.protocol, decoded);
    benchmark::DoNotOptimize(decoded);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_DecodeOwnMessage);

}  // namespace
BENCHMARK_MAIN();
