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

// Abandons every open candidate of the slot; the oldest is reported, the newer ones lie inside
// its bytes.
void Reassembler::drop_all(Slot& slot, uint32_t id, ReassemblyError why, Micros ts,
                           FrameSink& sink) {
  const uint16_t bytes = slot.have;
  slot.have = 0;
  slot.count = 0;
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
    drop_all(slot, can.id, ReassemblyError::kGapTimeout, ts, sink);
  }
  if (slot.have == 0) {
    start(slot, can, ts, sink);
  } else {
    append(slot, can, ts, sink);
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
  if (can.len < 8) {
    // Every message is at least 11 bytes: a short first segment can never complete.
    fail(ReassemblyError::kTruncated, can.id, ts, can.len, sink);
    return;
  }
  std::copy_n(can.data.begin(), can.len, slot.buf.begin());
  slot.have = can.len;
  slot.count = 1;
  slot.candidates[0] = Candidate{0, static_cast<uint16_t>(length + 9)};
  slot.last = ts;
}

void Reassembler::append(Slot& slot, const CanFrame& can, Micros ts, FrameSink& sink) {
  // The oldest open candidate starts at 0 and is incomplete, so have <= 256 and 8 more fit.
  if (can.len == 8 && plausible_start(can) && slot.count < kMaxCandidates) {
    slot.candidates[slot.count++] = Candidate{slot.have, static_cast<uint16_t>(can.data[3] + 9)};
  }
  const std::size_t take = std::min<std::size_t>(can.len, slot.buf.size() - slot.have);
  std::copy_n(can.data.begin(), take, slot.buf.begin() + slot.have);
  slot.have = static_cast<uint16_t>(slot.have + take);
  slot.last = ts;
  const bool last_segment = can.len < 8;  // only the last segment may be short

  // The first candidate (oldest first) that completes with a valid frame wins; candidates older
  // than it were abandoned by the sender, newer ones are its payload.
  const uint16_t restart_bytes = slot.count > 1 ? slot.candidates[1].start : slot.have;
  const uint16_t oldest_need = slot.candidates[0].need;
  std::size_t kept = 0;
  bool oldest_failed = false;
  ReassemblyError oldest_why = ReassemblyError::kCount;
  for (std::size_t i = 0; i < slot.count; ++i) {
    const Candidate c = slot.candidates[i];
    ReassemblyError why = ReassemblyError::kCount;
    if (slot.have - c.start >= c.need) {
      why = check(slot, c, static_cast<uint16_t>(can.id));
      if (why == ReassemblyError::kCount) {
        if (i > 0) fail(ReassemblyError::kRestarted, can.id, ts, restart_bytes, sink);
        slot.have = 0;
        slot.count = 0;
        emit(ts, sink);
        return;
      }
    } else if (last_segment) {
      why = ReassemblyError::kTruncated;
    } else {
      slot.candidates[kept++] = c;
      continue;
    }
    if (i == 0) {
      oldest_failed = true;
      oldest_why = why;
    }
  }
  if (oldest_failed) {
    if (kept > 0) {
      fail(ReassemblyError::kRestarted, can.id, ts, restart_bytes, sink);
    } else {
      fail(oldest_why, can.id, ts, std::min(slot.have, oldest_need), sink);
    }
  }
  // Re-base the stream on the oldest survivor.
  slot.count = static_cast<uint8_t>(kept);
  if (kept == 0) {
    slot.have = 0;
    return;
  }
  const uint16_t base = slot.candidates[0].start;
  if (base > 0) {
    std::copy(slot.buf.begin() + base, slot.buf.begin() + slot.have, slot.buf.begin());
    slot.have = static_cast<uint16_t>(slot.have - base);
    for (std::size_t i = 0; i < kept; ++i) slot.candidates[i].start -= base;
  }
}

ReassemblyError Reassembler::check(const Slot& slot, const Candidate& c, uint16_t can_id) {
  const std::span<const uint8_t> bytes(slot.buf.data() + c.start, c.need);
  // The header was validated when the candidate started; check what only the end can tell.
  if (bytes[c.need - 1] != kTail) return ReassemblyError::kBadTail;
  if (bytes[5] != bytes[3] - 2) return ReassemblyError::kLengthMismatch;
  ParseResult parsed = parse_frame(can_id, bytes, options_.crc_order);
  if (!parsed.ok()) return ReassemblyError::kBadCrc;
  scratch_ = parsed.frame;
  scratch_crc_ = parsed.crc_seen;
  return ReassemblyError::kCount;
}

void Reassembler::emit(Micros ts, FrameSink& sink) {
  ++stats_.frames_ok;
  if (scratch_crc_ == CrcOrder::kLittle) {
    ++stats_.crc_little_endian;
  } else {
    ++stats_.crc_big_endian;
  }
  sink.on_frame(scratch_, ts);
}

void Reassembler::expire(Micros now, FrameSink& sink) {
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    Slot& slot = slots_[i];
    if (slot.have > 0 && now - slot.last > options_.gap_timeout) {
      drop_all(slot, static_cast<uint32_t>(0x700 + i), ReassemblyError::kGapTimeout, now, sink);
    }
  }
}

}  // namespace motinova
