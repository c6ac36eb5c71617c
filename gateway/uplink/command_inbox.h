// Internal to the uplink: the command side of its state (uplink.h "Commands"), used by
// uplink_commands.cc. The lanes and their bounds are the contract of uplink.h; this holds the
// owner's half of them.
//
// Contract: `authenticator` is set before start() and only read afterwards (by Paho's thread);
// everything else is touched only on the owner's thread, inside Uplink's methods.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/uplink/uplink.h"
#include "gateway/uplink/uplink_events.h"

namespace fleetgw::uplink::detail {

// Busy notices waiting at most: about 200 bytes each, so at most ~200 KB for a backend that
// sends over a thousand commands faster than the owner's thread can answer them.
inline constexpr std::size_t kMaxBusyCommands = 1024;
// Unauthenticated payloads waiting on Paho's side at most.
inline constexpr std::size_t kMaxQueuedUnauthenticated = 4;
// Unauthenticated payloads handed to take_commands(): a token bucket of this many, refilled at
// kUnauthenticatedPerMinute, on the `now` timeline. The command service answers as many
// (unauthenticated_results_per_minute, 30), so nothing it would answer is held back.
inline constexpr double kUnauthenticatedBurst = 10;
inline constexpr double kUnauthenticatedPerMinute = 30;
// A drop class is logged at most this often (with the number suppressed in between).
inline constexpr std::chrono::seconds kDropLogInterval{10};

// Dropped commands (and zone bundles) at least this large are followed by a heap trim: glibc
// keeps freed memory of a large message in the process otherwise (issue 11, item 8).
inline constexpr std::size_t kTrimAfterBytes = 256 * 1024;

inline constexpr std::size_t kDropClasses = 4;
// "oversized", "undecodable", "unauthenticated", "queue_full" (the status document's keys).
std::string_view drop_class_name(CommandDropClass c);

struct CommandInbox {
  struct Waiting {
    std::string payload;
    bool authenticated = true;
  };
  CommandAuthenticator authenticator;  // empty: one lane, no busy notices (uplink.h)
  std::vector<Waiting> waiting;        // for take_commands()
  std::vector<BusyCommand> busy;       // for take_busy_commands()
  double unauthenticated_tokens = kUnauthenticatedBurst;
  std::chrono::microseconds tokens_at{0};
  bool tokens_started = false;
  // Per drop class: when it was last logged (nothing logged yet: not set) and how many were
  // dropped since without a log line.
  std::array<std::chrono::microseconds, kDropClasses> logged_at{};
  std::array<bool, kDropClasses> ever_logged{};
  std::array<std::uint64_t, kDropClasses> suppressed{};
};

// Paho's thread: sorts one payload on the cmd topic into its lane, or drops it (an event
// either way). `authenticator` may be empty (one lane, uplink.h).
void triage_command(std::string_view payload, const UplinkConfig& config,
                    const CommandAuthenticator& authenticator, EventQueue& events);
// The owner's thread: counts a drop by class and logs it (at most once per kDropLogInterval per
// class, with the number suppressed since).
void record_drop(CommandInbox& inbox, UplinkStats& counters, const std::string& topic,
                 std::chrono::microseconds now, const CommandDropped& e);

}  // namespace fleetgw::uplink::detail
