// Per-CAN-ID reassembly of application frames from CAN segments (spec §2.2, §2.6).
//
// Contract:
//  * One independent buffer per MOTINOVA ID (0x700-0x7FF): traffic on one ID never disturbs
//    another. Memory is fixed (256 buffers of kMaxFrameSize bytes); nothing is allocated per frame.
//  * A message starts on a CAN frame whose first two bytes are 55 AA; LENGTH + 9 bytes are
//    collected, then tail, n == LENGTH - 2 and CRC are checked. Surplus bytes in the last segment
//    are ignored (padding to DLC 8).
//  * A partial message is dropped when the next segment arrives more than `gap_timeout` later,
//    or when a segment that starts with a plausible header (55 AA, valid MODE, LENGTH >= 2,
//    n == LENGTH - 2) arrives on the same ID mid-way: the sender restarted, the new start is kept.
//    (A data segment that merely begins with 55 AA is continued: a plausible header by chance
//    has a probability below 1e-9.)
//  * Every dropped byte sequence is reported to the sink once, with its kind, and counted.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "motinova/can.h"
#include "motinova/frame.h"

namespace motinova {

enum class ReassemblyError : uint8_t {
  kBadHeader,       // CAN frame outside a message that does not start with 55 AA (discarded)
  kBadMode,         // MODE byte invalid in a starting segment
  kBadLength,       // LENGTH < 2
  kLengthMismatch,  // n != LENGTH - 2
  kBadTail,         // byte LENGTH + 8 is not F0
  kBadCrc,          // CRC mismatch
  kTruncated,       // a short (final) segment arrived before LENGTH + 9 bytes were collected
  kGapTimeout,      // partial message abandoned: next segment too late (or flushed by expire())
  kRestarted,       // partial message abandoned: a new 55 AA start arrived on the same ID
  kForeignId,       // CAN ID outside 0x700-0x7FF, or extended/remote/error frame (ignored)
  kCount
};
inline constexpr std::size_t kReassemblyErrorKinds =
    static_cast<std::size_t>(ReassemblyError::kCount);
std::string_view reassembly_error_name(ReassemblyError e);

struct ReassemblyErrorEvent {
  ReassemblyError kind;
  uint32_t can_id;
  Micros timestamp;
  uint16_t bytes_dropped;  // bytes of the abandoned message or discarded CAN frame
};

struct ReassemblerStats {
  uint64_t can_frames = 0;
  uint64_t frames_ok = 0;
  uint64_t crc_big_endian = 0;  // valid frames whose CRC matched big-endian (U1)
  uint64_t crc_little_endian = 0;
  std::array<uint64_t, kReassemblyErrorKinds> errors{};
  uint64_t error(ReassemblyError e) const { return errors[static_cast<std::size_t>(e)]; }
  uint64_t total_errors() const;
};

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual void on_frame(const AppFrame& frame, Micros timestamp) = 0;
  virtual void on_error(const ReassemblyErrorEvent& error) = 0;
};

struct ReassemblerOptions {
  Micros gap_timeout{100'000};  // U15
  CrcOrder crc_order = CrcOrder::kBig;
};

class Reassembler {
 public:
  explicit Reassembler(ReassemblerOptions options = {});

  // Feeds one received CAN frame. `timestamp` is the receive time (monotonic is fine).
  void push(const CanFrame& can, Micros timestamp, FrameSink& sink);

  // Abandons every partial message whose last segment is older than gap_timeout at `now`.
  void expire(Micros now, FrameSink& sink);

  const ReassemblerStats& stats() const { return stats_; }
  const ReassemblerOptions& options() const { return options_; }
  void set_crc_order(CrcOrder order) { options_.crc_order = order; }

 private:
  struct Slot {
    std::array<uint8_t, kMaxFrameSize> buf{};
    uint16_t have = 0;  // bytes collected; 0 = idle
    uint16_t need = 0;  // LENGTH + 9 once known
    Micros last{0};
  };
  void drop(Slot& slot, uint32_t id, ReassemblyError why, Micros ts, FrameSink& sink);
  void fail(ReassemblyError why, uint32_t id, Micros ts, uint16_t bytes, FrameSink& sink);
  void start(Slot& slot, const CanFrame& can, Micros ts, FrameSink& sink);
  void finish(Slot& slot, uint32_t id, Micros ts, FrameSink& sink);

  ReassemblerOptions options_;
  std::array<Slot, 256> slots_{};
  ReassemblerStats stats_;
  AppFrame scratch_;
};

}  // namespace motinova
