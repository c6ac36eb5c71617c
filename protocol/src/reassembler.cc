#include "motinova/reassembler.h"

#include <algorithm>
#include <numeric>

namespace motinova {
namespace {

bool starts_with_header(const CanFrame& can) {
  return can.len >= 2 && can.data[0] == kHeader0 && can.data[1] == kHeader1;
}

// A segment that could be the first of a new message (used to detect a sender restart).
bool plausible_start(const CanFrame& can) {
  return can.len >= 6 && starts_with_header(can) && is_valid_mode(can.data[2]) &&
         can.data[3] >= 2 && can.data[5] == can.data[3] - 2;
}

}  // namespace

std::string_view reassembly_error_name(ReassemblyError e) {
  switch (e) {
    case ReassemblyError::kBadHeader:
      return "bad_header";
    case ReassemblyError::kBadMode:
      return "bad_mode";
    case ReassemblyError::kBadLength:
      return "bad_length";
    case ReassemblyError::kLengthMismatch:
      return "length_mismatch";
    case ReassemblyError::kBadTail:
      return "bad_tail";
    case ReassemblyError::kBadCrc:
      return "bad_crc";
    case ReassemblyError::kTruncated:
      return "truncated";
    case ReassemblyError::kGapTimeout:
      return "gap_timeout";
    case ReassemblyError::kRestarted:
      return "restarted";
    case ReassemblyError::kForeignId:
      return "foreign_id";
    case ReassemblyError::kCount:
      break;
  }
  return "unknown";
}

uint64_t ReassemblerStats::total_errors() const {
  return std::accumulate(errors.begin(), errors.end(), uint64_t{0});
}

Reassembler::Reassembler(ReassemblerOptions options) : options_(options) {}

void Reassembler::fail(ReassemblyError why, uint32_t id, Micros ts, uint16_t bytes,
                       FrameSink& sink) {
  ++stats_.errors[static_cast<std::size_t>(why)];
  sink.on_error(ReassemblyErrorEvent{why, id, ts, bytes});
}

void Reassembler::drop(Slot& slot, uint32_t id, ReassemblyError why, Micros ts, FrameSink& sink) {
  const uint16_t bytes = slot.have;
  slot.have = 0;
  slot.need = 0;
  fail(why, id, ts, bytes, sink);
}

void Reassembler::push(const CanFrame& can, Micros ts, FrameSink& sink) {
  ++stats_.can_frames;
  if (!is_motinova_id(can.id) || can.len > 8) {
    fail(ReassemblyError::kForeignId, can.id, ts, can.len, sink);
    return;
  }
  Slot& slot = slots_[can.id & 0xFF];
  if (slot.have > 0 && ts - slot.last > options_.gap_timeout) {
    drop(slot, can.id, ReassemblyError::kGapTimeout, ts, sink);
  }
  if (slot.have > 0 && plausible_start(can)) {
    drop(slot, can.id, ReassemblyError::kRestarted, ts, sink);
  }
  if (slot.have == 0) {
    start(slot, can, ts, sink);
    return;
  }
  const std::size_t take = std::min<std::size_t>(can.len, slot.need - slot.have);
  std::copy_n(can.data.begin(), take, slot.buf.begin() + slot.have);
  slot.have = static_cast<uint16_t>(slot.have + take);
  slot.last = ts;
  if (slot.have == slot.need) {
    finish(slot, can.id, ts, sink);
  } else if (can.len < 8) {
    // Only the last segment of a message may be shorter than 8 bytes.
    drop(slot, can.id, ReassemblyError::kTruncated, ts, sink);
  }
}

void Reassembler::start(Slot& slot, const CanFrame& can, Micros ts, FrameSink& sink) {
  if (!starts_with_header(can)) {
    fail(ReassemblyError::kBadHeader, can.id, ts, can.len, sink);
    return;
  }
  if (can.len < 4) {
    fail(ReassemblyError::kTruncated, can.id, ts, can.len, sink);
    return;
  }
  if (!is_valid_mode(can.data[2])) {
    fail(ReassemblyError::kBadMode, can.id, ts, can.len, sink);
    return;
  }
  const uint8_t length = can.data[3];
  if (length < 2) {
    fail(ReassemblyError::kBadLength, can.id, ts, can.len, sink);
    return;
  }
  if (can.len >= 6 && can.data[5] != length - 2) {
    fail(ReassemblyError::kLengthMismatch, can.id, ts, can.len, sink);
    return;
  }
  slot.need = static_cast<uint16_t>(length + 9);
  const std::size_t take = std::min<std::size_t>(can.len, slot.need);
  std::copy_n(can.data.begin(), take, slot.buf.begin());
  slot.have = static_cast<uint16_t>(take);
  slot.last = ts;
  if (slot.have < slot.need && can.len < 8) {
    drop(slot, can.id, ReassemblyError::kTruncated, ts, sink);
  }
}

void Reassembler::finish(Slot& slot, uint32_t id, Micros ts, FrameSink& sink) {
  const std::span<const uint8_t> bytes(slot.buf.data(), slot.need);
  const auto can_id = static_cast<uint16_t>(id);
  // The structure was validated when the message started; check what only the end can tell.
  ReassemblyError why = ReassemblyError::kCount;
  if (bytes[slot.need - 1] != kTail) {
    why = ReassemblyError::kBadTail;
  } else if (bytes[5] != bytes[3] - 2) {
    why = ReassemblyError::kLengthMismatch;
  }
  if (why != ReassemblyError::kCount) {
    drop(slot, id, why, ts, sink);
    return;
  }
  ParseResult parsed = parse_frame(can_id, bytes, options_.crc_order);
  if (!parsed.ok()) {
    drop(slot, id, ReassemblyError::kBadCrc, ts, sink);
    return;
  }
  slot.have = 0;
  slot.need = 0;
  ++stats_.frames_ok;
  if (parsed.crc_seen == CrcOrder::kLittle) {
    ++stats_.crc_little_endian;
  } else {
    ++stats_.crc_big_endian;
  }
  scratch_ = parsed.frame;
  sink.on_frame(scratch_, ts);
}

void Reassembler::expire(Micros now, FrameSink& sink) {
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    Slot& slot = slots_[i];
    if (slot.have > 0 && now - slot.last > options_.gap_timeout) {
      drop(slot, static_cast<uint32_t>(0x700 + i), ReassemblyError::kGapTimeout, now, sink);
    }
  }
}

}  // namespace motinova
