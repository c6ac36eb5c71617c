// Internal to backend/ingest (used by envelope_rows.cc): the destination tables, the checked
// row builder and one function per Envelope body kind that appends that body's row.
//
// Contract:
//  * RowBuilder appends one value per call in the table's column order (COPY text, copy_text.h); a value PostgreSQL
//    could not store as sent (uint32 > 2^31-1, uint64 > 2^63-1, text with NUL or over kMaxText)
//    is recorded as the builder's first `error` (a Reject naming the field), never thrown.
//  * <kind>_rows(e, d, b) appends the row of e's body through `b` (whose values belong to a
//    RowSet of the kind's table in `d`), and sets d.records (and, for an eviction report, the
//    evicted range in d.ranges); callers check b.error afterwards.
//  * telemetry_rows() adds a RowSet of its own (one row per sample) and the samples' ranges.
#pragma once

#include <fmt/format.h>

#include <charconv>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "backend/ingest/copy_text.h"
#include "backend/ingest/envelope_rows.h"
#include "backend/ingest/safe_text.h"
#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::ingest::rows {

namespace v1 = fleetgw::v1;

extern const TableSpec kRides, kFaults, kTelemetry, kPacks, kLocks, kResults, kCommands, kInfo,
    kAlarms, kEvictions, kStatus, kState, kZones, kStatusHistory;

// Locks, faults or active alarms a VehicleState may name (a bike has a handful of each).
constexpr int kMaxStateEntries = 256;

// Appends one row's values with the checks of the contract, in COPY's text format straight
// into the RowSet's buffer (no string per value); the first failure is kept. A row is complete
// after table->column_count values.
class RowBuilder {
 public:
  explicit RowBuilder(RowSet& set)
      : set_(set), out_(set.copy), cols_(static_cast<std::size_t>(set.table->column_count)) {}

  void text(std::string_view field, std::string_view s) {
    check_text(field, s);
    raw(s);
  }
  // The checks of text() alone (for a value written many times through escaped()).
  void check_text(std::string_view field, std::string_view s) {
    if (s.size() > kMaxText) {
      fail("text_too_long", fmt::format("{}: {} bytes (at most {})", field, s.size(), kMaxText));
    } else if (s.find('\0') != std::string_view::npos) {
      fail("nul_in_text", fmt::format("{}: NUL byte in \"{}\"", field, untrusted_excerpt(s)));
    }
  }
  // `n` values already checked and in COPY text (escaped, tab-separated): the same leading
  // values of every row of a message (a telemetry batch's ids) are escaped once, not per row.
  void escaped(std::string_view values, std::size_t n) {
    begin_text();
    out_.append(values);
    col_ += n - 1;
    end();
  }
  void u32(std::string_view field, std::uint32_t v) {
    if (v > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max())) {
      fail("value_out_of_range", fmt::format("{}: {} above 2^31-1", field, v));
    }
    number(v);
  }
  void u64(std::string_view field, std::uint64_t v) {
    if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      fail("value_out_of_range", fmt::format("{}: {} above 2^63-1", field, v));
    }
    number(v);
  }
  void i64(std::int64_t v) { number(v); }
  void boolean(bool v) {
    char* p = room(2);
    if (col_ > 0) *p++ = '\t';
    *p++ = v ? 't' : 'f';
    used(p);
    end();
  }
  void null() {
    char* p = room(3);
    if (col_ > 0) *p++ = '\t';
    *p++ = '\\';
    *p++ = 'N';
    used(p);
    end();
  }
  // A value as it is (escaped for COPY): enum names, JSON, array literals, bytea hex.
  void raw(std::string_view v) {
    begin_text();
    append_copy_text(out_, v);
    end();
  }
  // An enum's proto name (its number when it has none: a value newer than this ingest).
  template <class Enum>
  void name(const std::string& (*name_of)(Enum), int value) {
    const std::string& n = name_of(static_cast<Enum>(value));
    n.empty() ? number(value) : raw(n);
  }
  template <class T>
  void opt_u32(std::string_view field, bool has, T v) {
    has ? u32(field, v) : null();
  }
  template <class T>
  void opt_u64(std::string_view field, bool has, T v) {
    has ? u64(field, v) : null();
  }
  void opt_i64(bool has, std::int64_t v) { has ? i64(v) : null(); }
  void position(bool has, const v1::Position& p) {
    if (has) {
      i64(p.lat_e7());
      i64(p.lon_e7());
    } else {
      null();
      null();
    }
  }

  void fail(std::string_view code, std::string detail) {
    if (!error) error = Reject{std::string(code), std::move(detail)};
  }
  std::optional<Reject> error;

 private:
  // Numbers, NULLs, booleans and separators go into the builder's own small buffer, appended
  // to the RowSet's text when it fills, before a text value and at the end of each row: a
  // std::string append of 1-20 bytes each (a capacity check and a memcpy call) was ~5 % of the
  // worker's CPU in a drain (issue 25). A row is in set_.copy once its last value is written.
  char* room(std::size_t n) {
    if (pending_ + n > sizeof buf_) flush();
    return buf_ + pending_;
  }
  void used(const char* end) { pending_ = static_cast<std::size_t>(end - buf_); }
  void flush() {
    out_.append(buf_, pending_);
    pending_ = 0;
  }
  // Before a value appended to the text directly: the buffer and the separator go first.
  void begin_text() {
    if (col_ > 0) buf_[pending_++] = '\t';  // room: end() leaves one byte at least
    flush();
  }
  void end() {
    if (pending_ == sizeof buf_) flush();
    if (++col_ < cols_) return;
    buf_[pending_++] = '\n';
    flush();
    col_ = 0;
    ++set_.row_count;
  }
  template <class T>
  void number(T v) {
    char* p = room(1 + 24);
    if (col_ > 0) *p++ = '\t';
    used(std::to_chars(p, buf_ + sizeof buf_, v).ptr);
    end();
  }

  RowSet& set_;
  std::string& out_;
  std::size_t cols_;
  std::size_t col_ = 0;
  char buf_[512];
  std::size_t pending_ = 0;
};

template <class Enum>
std::string enum_name(const std::string& (*name)(Enum), int value) {
  const std::string& n = name(static_cast<Enum>(value));
  return n.empty() ? std::to_string(value) : n;
}

// The record header: sequence rules and the five shared columns.
struct Header {
  const v1::Envelope& e;
  void add(RowBuilder& b) const {
    b.text("vehicle_id", e.vehicle_id());
    b.text("store_id", e.store_id());
    b.u64("sequence", e.sequence());
    b.i64(e.created_at_us());
    b.text("gateway_fw_version", e.gateway_fw_version());
  }
};

// A RowSet of t in d, with room for `rows` rows.
RowSet& new_rows(Decoded& d, const TableSpec& t, std::size_t rows = 1);

void ride_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void fault_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void pack_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void lock_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void result_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void info_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void alarm_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void zone_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void eviction_rows(const v1::Envelope& e, Decoded& d, RowBuilder& b);
void status_rows(const v1::Envelope& e, RowBuilder& b);
void state_rows(const v1::Envelope& e, RowBuilder& b);
// The status's row of status_history (a RowSet of its own in d).
void status_history_rows(const v1::Envelope& e, Decoded& d);
std::optional<Reject> telemetry_rows(const v1::Envelope& e, Decoded& d);

}  // namespace fleetgw::ingest::rows
