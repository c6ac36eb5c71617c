// libFuzzer target: arbitrary bytes become a stream of CAN frames on MOTINOVA IDs, fed through
// the reassembler (every CRC order) and every decoded frame through the decoder (every byte
// order and fault layout). Invariants checked beyond "no crash, no sanitizer report":
//  * a reported frame re-encodes to bytes that parse back to the same frame;
//  * the error counters equal the error events reported.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "motinova/codec.h"
#include "motinova/frame.h"
#include "motinova/reassembler.h"

namespace {

using namespace motinova;

struct CheckingSink : FrameSink {
  const DecodeOptions* options = nullptr;
  DecodedMessage decoded;
  uint64_t errors = 0;
  void on_frame(const AppFrame& frame, Micros) override {
    const auto bytes = encode_frame(frame, CrcOrder::kBig);
    const auto again = parse_frame(frame.can_id, bytes.span(), CrcOrder::kBig);
    if (!again.ok() || !(again.frame == frame)) std::abort();
    decode(frame, Catalogue::standard(), *options, decoded);
    volatile double sink = 0;
    for (const auto& v : decoded.values()) sink = sink + v.value + static_cast<double>(v.raw);
  }
  void on_error(const ReassemblyErrorEvent&) override { ++errors; }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  DecodeOptions options;
  const uint8_t selector = data[0];
  options.data_order = (selector & 1) ? ByteOrder::kLittle : ByteOrder::kBig;
  options.mc_fault_layout = static_cast<FaultWordLayout>((selector >> 1) % 3);
  options.bms_fault_layout = static_cast<FaultWordLayout>((selector >> 3) % 3);
  options.mc_voltage_current_order = static_cast<McVoltageCurrentOrder>((selector >> 5) % 3);
  options.bms_current_charge_positive = (selector & 0x80) != 0;
  const CrcOrder crc_order = static_cast<CrcOrder>(selector % 3);
  // The readings made configurable by issue 11 (U11, U14, U17), from the same selector bits.
  options.mc_answer_id = static_cast<McAnswerId>((selector >> 1) % 4);
  options.wheel_size_unit = static_cast<WheelSizeUnit>((selector >> 3) % 3);
  options.wheel_adjust_unit = static_cast<WheelAdjustUnit>((selector >> 5) & 1);
  options.pack_stats_discharge_current_first = (selector & 0x40) != 0;
  options.pack_stats_time_unit = static_cast<PackTimeUnit>((selector >> 2) & 1);
  if (selector & 0x10) {
    std::reverse(options.pack_stats_counter_order.begin(), options.pack_stats_counter_order.end());
  }

  Reassembler reassembler(
      ReassemblerOptions{.gap_timeout = Micros(100'000), .crc_order = crc_order});
  CheckingSink sink;
  sink.options = &options;
  Micros now{0};
  std::size_t i = 1;
  // Frame encoding: [id low byte][flags: len (low 4 bits, clamped to 8), time step (high 4)]
  // followed by len payload bytes.
  while (i + 2 <= size) {
    CanFrame can;
    can.id = 0x700u | data[i];
    const uint8_t flags = data[i + 1];
    can.len = static_cast<uint8_t>(std::min<unsigned>(flags & 0x0F, 8));
    now += Micros((flags >> 4) * 20'000);
    i += 2;
    for (uint8_t k = 0; k < can.len && i < size; ++k) can.data[k] = data[i++];
    reassembler.push(can, now, sink);
  }
  reassembler.expire(now + Micros(1'000'000), sink);
  if (sink.errors != reassembler.stats().total_errors()) std::abort();

  // The whole input is also tried as one application frame.
  const auto parsed = parse_frame(0x710, {data + 1, size - 1}, CrcOrder::kAuto);
  if (parsed.ok()) {
    DecodedMessage decoded;
    decode(parsed.frame, Catalogue::standard(), options, decoded);
  }
  return 0;
}
