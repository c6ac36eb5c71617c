// Remote diagnostics (issue 29): the table of the spec's on-demand blocks a signed diagnostic
// read may ask for -- which request the gateway sends, on which ID, and which answer it waits
// for -- and the decoding of an answer into a fleetgw.v1.DiagnosticMessage named with the
// signal catalogue (protocol/signal_catalogue.h).
//
// Contract:
//  * Pure: no clock, no bus, no storage. The table is immutable (built once).
//  * Every request in the table is a READ (mode 0x11, no data): a diagnostic read never writes
//    to a node. tests/command/test_diag.cc checks that for every block.
//  * Answers are matched by (CAN ID, function) like every request of the IoT node: MC answers
//    on 0x713 (U14: also 0x710 and 0x716), the others on their broadcast or CDL ID.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/verifier.h"
#include "gateway/node/messages.h"
#include "motinova/can.h"
#include "motinova/frame.h"
#include "motinova/options.h"

namespace fleetgw::command {

// One request and the answers that complete it.
struct DiagStep {
  std::uint16_t request_id = 0;  // 0: nothing is sent, the next answer broadcast is awaited
  std::uint8_t request_function = 0;
  std::vector<node::MessageKey> answers;
  std::string_view answer_name;  // catalogue name of the answer ("mc_lifetime_2")
  bool optional = false;         // missing: the block is still answered, with a note
};

struct DiagBlockSpec {
  v1::DiagnosticBlock block = v1::DIAGNOSTIC_BLOCK_UNSPECIFIED;
  std::string_view name;  // "mc_settings" (CLI and DiagnosticResult.block)
  motinova::Node node = motinova::Node::kMc;
  std::vector<DiagStep> steps;  // run in order
  bool capturable = false;      // a lifetime record: last_captured may answer it
};

// Every block, in enum order (DIAGNOSTIC_BLOCK_LOCK_MODEL with lock 1; see lock_model_block).
std::span<const DiagBlockSpec> diag_blocks();
const DiagBlockSpec* find_diag_block(v1::DiagnosticBlock block);
const DiagBlockSpec* find_diag_block(std::string_view name);
// The lock-model read for lock k (0-based): 0x767+k read F<<8 -> 0x7n0/0x1240.
DiagBlockSpec lock_model_block(int k);
// "mc_settings, mc_params, ..." for usage messages.
std::string diag_block_names();

// Checks a received DiagnosticRead (malformed detail when it is not a valid read) and fills
// `out`. Used by the verifier.
std::optional<std::string> parse_diag_read(const v1::DiagnosticRead& read, DiagRequest& out);

// "0x761/0x3300": a request's ID and COMMAND as the spec writes them.
std::string diag_request_text(const DiagStep& step);
// "the MC (node 1)".
std::string diag_node_text(motinova::Node node);

// Decodes one answer frame into `out`: catalogue name, ID, COMMAND, the DATA bytes and every
// signal of the message (name, type, unit, text, value_e6, valid). `heard_wall_us`: when it was
// heard, wall clock.
void decode_diag_message(const motinova::AppFrame& frame, const motinova::DecodeOptions& options,
                         std::int64_t heard_wall_us, v1::DiagnosticMessage& out);

}  // namespace fleetgw::command
