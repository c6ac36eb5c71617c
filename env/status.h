// Status and Result<T>: the one error type of the gateway's hot path (a store write, a recorder
// flush, an uplink publish or ack, a stage's run). Exceptions stay at the edges: configuration,
// opening files and databases, the command-line tools.
//
// Contract:
//  * A Status is ok (code kOk, empty message) or an error: a code a caller can act on (retry a
//    kFull or kIo later, drop a kInvalid batch, back off after kUnavailable...) and a message for
//    a human that names what failed and where ("storage: Batch.rides[1].ride_id: empty"). The
//    message is what the logs and `fleetgw status` show; the code is what callers branch on.
//  * Result<T> holds a T or an error Status, never both, never an ok Status without a value:
//    built from an ok Status it holds a kOther error saying so (a programming error, reported
//    instead of hidden). status() of a value is the ok Status. value() on an error is a
//    programming error (asserted in debug builds); callers test ok() first.
//  * Plain values: copyable and movable (a Result as much as its T), no allocation beyond the
//    message; no dependency beyond the standard library (g++ 12 has no std::expected).
#pragma once

#include <cassert>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace fleetgw {

enum class StatusCode : std::uint8_t {
  kOk,
  kFull,         // out of space (disk full, budget reached): retry once space returns
  kIo,           // an I/O error from the OS or SQLite: retry later
  kInvalid,      // the input was refused: retrying the same input fails the same way
  kUnavailable,  // the peer is not there (MQTT not connected): retry after reconnecting
  kRefused,      // the peer refused it (broker reason code, ACL)
  kOther,        // anything else (an SQLite error that is none of the above)
};

// "ok", "full", "io", "invalid", "unavailable", "refused", "other".
std::string_view to_string(StatusCode code);

struct Status {
  using Code = StatusCode;

  Code code = Code::kOk;
  std::string message;

  static Status error(Code code, std::string message) { return {code, std::move(message)}; }
  bool ok() const { return code == Code::kOk; }
  friend bool operator==(const Status&, const Status&) = default;
};

template <class T>
class Result {
 public:
  Result(T value) : v_(std::in_place_index<0>, std::move(value)) {}  // NOLINT: implicit by design
  Result(Status error) : v_(std::in_place_index<1>, std::move(error)) {  // NOLINT
    auto& s = std::get<1>(v_);
    if (s.ok()) s = Status::error(StatusCode::kOther, "an ok Status given as a Result's error");
  }

  bool ok() const { return v_.index() == 0; }

  T& value() & {
    assert(ok());
    return std::get<0>(v_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<0>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<0>(std::move(v_));
  }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  // The value, or `fallback` on an error (a caller that only needs a count).
  T value_or(T fallback) const& { return ok() ? std::get<0>(v_) : std::move(fallback); }

  // The error; the ok Status when the Result holds a value.
  Status status() const { return ok() ? Status{} : std::get<1>(v_); }

 private:
  std::variant<T, Status> v_;
};

}  // namespace fleetgw
