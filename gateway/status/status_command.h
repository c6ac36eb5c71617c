// `fleetgw status`: ask the running service for its status document and show it.
//
// Contract:
//  * Connects to the status socket, reads one JSON document (status_server.h) within `timeout`,
//    and prints either the human summary (status_report.h) or the raw JSON (json = true, one
//    pretty-printed document on `out`).
//  * Exit codes, for monitoring scripts:
//      0  everything fine,
//      1  the service answered and something needs attention (the rules in status_report.h),
//      3  no answer: cannot connect, the service did not answer within `timeout` (a hung event
//         loop looks like this), or the answer is not JSON.
//    Problems reaching the service are explained on `err`.
#pragma once

#include <chrono>
#include <iostream>
#include <ostream>
#include <string>

#include "gateway/status/status_report.h"
#include "gateway/status/status_server.h"

namespace fleetgw::status {

inline constexpr int kStatusOk = 0;
inline constexpr int kStatusAttention = 1;
inline constexpr int kStatusUnreachable = 3;

struct StatusCommandOptions {
  std::string socket_path = kDefaultStatusSocket;
  bool json = false;
  AttentionRules rules;
  std::chrono::milliseconds timeout{5000};
};

int run_status_command(const StatusCommandOptions& options, std::ostream& out, std::ostream& err);

// Shorthand with the default rules and timeout; problems go to std::cerr.
int run_status_command(const std::string& socket_path, bool json_output, std::ostream& out);

}  // namespace fleetgw::status
