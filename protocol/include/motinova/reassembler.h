// Per-CAN-ID reassembly of application frames from CAN segments (spec §2.2, §2.6).
//
// Contract:
//  * One independent buffer per MOTINOVA ID (0x700-0x7FF): traffic on one ID never disturbs
//    another. Memory is fixed (256 buffers of kMaxFrameSize bytes plus at most kMaxSegments
//    candidate starts each); nothing is allocated per frame.
//  * A message starts on a CAN frame whose first two bytes are 55 AA; LENGTH + 9 bytes are
//    collected, then tail, n == LENGTH - 2 and CRC are checked. Surplus bytes in the last segment
//    are ignored (padding to DLC 8).
//  * Segment content never ends a message (spec §2.2 has no such rule). A full segment that
//    looks like a header (55 AA, valid MODE, LENGTH >= 2, n == LENGTH - 2) arriving mid-way may
//    be payload (a current of 0x55AA...) or a sender restart: both readings are kept side by
//    side as candidates over the same byte stream, and whichever completes with a valid CRC is
//    emitted; the others are discarded. Every live candidate started within the last 33
//    segments (a message spans at most 33), so kMaxSegments candidates always suffice.
//  * A partial message is dropped when the next segment arrives more than `gap_timeout` later,
//    or when a short segment ends it early (only the last segment may be shorter than 8).
//  * Every dropped message is reported to the sink once, with its kind, and counted. A candidate
//    that fails while an older one is still open was payload and is dropped silently; the oldest
//    failing while a newer start is open is reported as kRestarted (bytes before the new start).
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
  static constexpr std::size_t kMaxCandidates = (kMaxFrameSize + 7) / 8;  // 33

  // A possible message start inside the slot's byte stream.
  struct Candidate {
    uint16_t start = 0;  // offset in Slot::buf (a multiple of 8)
    uint16_t need = 0;   // LENGTH + 9
  };
  // The bytes received on one ID since the oldest open candidate started (it starts at 0).
  struct Slot {
    std::array<uint8_t, kMaxFrameSize> buf{};
    uint16_t have = 0;  // stream bytes held; 0 = idle
    uint8_t count = 0;  // open candidates, oldest first
    std::array<Candidate, kMaxCandidates> candidates{};
    Micros last{0};
  };
  void drop_all(Slot& slot, uint32_t id, ReassemblyError why, Micros ts, FrameSink& sink);
  void fail(ReassemblyError why, uint32_t id, Micros ts, uint16_t bytes, FrameSink& sink);
  void start(Slot& slot, const CanFrame& can, Micros ts, FrameSink& sink);
  void append(Slot& slot, const CanFrame& can, Micros ts, FrameSink& sink);
  // kCount when the candidate's bytes are a valid frame (left in scratch_), else why not.
  ReassemblyError check(const Slot& slot, const Candidate& c, uint16_t can_id);
  void emit(Micros ts, FrameSink& sink);

  ReassemblerOptions options_;
  std::array<Slot, 256> slots_{};
  ReassemblerStats stats_;
  AppFrame scratch_;
  CrcOrder scratch_crc_ = CrcOrder::kBig;
};

}  // namespace motinova
