// BMS (node 2) messages of V4.6.2: broadcasts on 0x720, the handshake answer on 0x721, pack
// statistics for the CDL on 0x725, and the reads of BMS blocks by the OBC (0x732), the IOT
// (0x762) and the CDL (0x752). Spec §3.1 and §3.3.

#include "catalogue_tables.h"

namespace motinova::detail {
namespace {

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
// 0x720/0x1010 BMS status (§3.3.1). Current sign convention: U4. Byte 10 is exposed both as
// the raw flags and as the "charging" bit.
constexpr FieldDesc kBmsStatus[] = {
    {.name = "voltage_v", .offset = 0, .size = 2, .scale = 0.001, .unit = "V"},
    {.name = "current_a", .offset = 2, .size = 2, .kind = FieldKind::kSigned, .scale = 0.001, .quirk = Quirk::kBmsCurrent, .unit = "A"},
    {.name = "remaining_mah", .offset = 4, .size = 2, .unit = "mAh"},
    {.name = "full_mah", .offset = 6, .size = 2, .unit = "mAh"},
    {.name = "temp_c", .offset = 8, .bias = kTempBias, .unit = "°C"},
    {.name = "soc_pct", .offset = 9, .unit = "%"},
    {.name = "charging", .offset = 10, .kind = FieldKind::kBool, .bool_mask = 0x01},
    {.name = "state_flags", .offset = 10, .kind = FieldKind::kFlags},  // 0x02 unknown (U5)
    {.name = "soh_pct", .offset = 11, .unit = "%"},
    {.name = "cycles", .offset = 12, .size = 2},
    {.name = "charge_time_min", .offset = 14, .size = 2, .unit = "min"},  // U5
};

// 0x720/0x1120 cell voltages 1..16 (§3.3.2) [C]; unused cells are 0.
constexpr FieldDesc kBmsCells[] = {
    {.name = "cells_mv", .offset = 0, .size = 2, .kind = FieldKind::kArray, .count = 16, .unit = "mV"},
};

// 0x720/0x1410 battery nameplate (§3.3.5); bytes 3..11 are U22.
constexpr FieldDesc kBmsNameplate[] = {
    {.name = "rated_capacity_mah", .offset = 0, .size = 2, .unit = "mAh"},
    {.name = "rated_voltage_v", .offset = 2, .unit = "V"},
    {.name = "date_text", .offset = 3, .size = 8, .kind = FieldKind::kAscii},  // '/'-separated
    {.name = "max_current_a", .offset = 11, .unit = "A"},
    {.name = "reserved", .offset = 12, .size = 4, .kind = FieldKind::kReserved},
};

// 0x720/0x1810 extra temperatures / times (§3.3.7), names U22.
constexpr FieldDesc kBmsTemps[] = {
    {.name = "temp_max_c", .offset = 0, .bias = kTempBias, .unit = "°C"},
    {.name = "temp_min_c", .offset = 1, .bias = kTempBias, .unit = "°C"},
    {.name = "value_1", .offset = 2, .size = 2},
    {.name = "time_2", .offset = 4, .size = 2},
    {.name = "reserved", .offset = 6, .size = 10, .kind = FieldKind::kReserved},
};

// 0x725/0x5028 pack lifetime statistics (§3.3.10); counter order and time units are U17.
constexpr FieldDesc kPackStats[] = {
    {.name = "max_temp_c", .offset = 0, .bias = kTempBias, .unit = "°C"},
    {.name = "min_temp_c", .offset = 1, .bias = kTempBias, .unit = "°C"},
    {.name = "max_discharge_current_a", .offset = 2, .size = 2, .scale = 0.001, .quirk = Quirk::kPackDischargeCurrent, .unit = "A"},
    {.name = "max_charge_current_a", .offset = 4, .size = 2, .scale = 0.001, .quirk = Quirk::kPackChargeCurrent, .unit = "A"},
    {.name = "cycles", .offset = 6, .size = 2},
    {.name = "charge_time_total_h", .offset = 8, .size = 2, .quirk = Quirk::kPackTime, .unit = "h"},
    {.name = "charge_time_longest_h", .offset = 10, .size = 2, .quirk = Quirk::kPackTime, .unit = "h"},
    {.name = "over_charge_count", .offset = 12, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "over_discharge_count", .offset = 14, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "charge_over_current_count", .offset = 16, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "discharge_over_current_count", .offset = 18, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "short_circuit_count", .offset = 20, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "charge_over_temp_count", .offset = 22, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "charge_under_temp_count", .offset = 24, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "discharge_over_temp_count", .offset = 26, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "discharge_under_temp_count", .offset = 28, .size = 2, .quirk = Quirk::kPackCounter},
    {.name = "runtime_min", .offset = 30, .size = 4, .unit = "min"},
    {.name = "soh_pct", .offset = 34, .unit = "%"},
    {.name = "reserved", .offset = 35, .size = 5, .kind = FieldKind::kReserved},
};
// clang-format on

constexpr uint16_t kBmsBroadcast = 0x720;
constexpr uint16_t kBmsToMc = 0x721;
constexpr uint16_t kBmsToCdl = 0x725;
constexpr uint16_t kObcToBms = 0x732;
constexpr uint16_t kCdlToBms = 0x752;
constexpr uint16_t kIotToBms = 0x762;

// The block reads of §3.3.9. Answers are self-describing 0x720 frames; the probable pairing
// (U16) is only in the titles.
void append_block_reads(std::vector<MessageDesc>& out, uint16_t id) {
  out.push_back(read_request("read_bms_status", id, 0x50, "read BMS block (probably 0x1010)"));
  out.push_back(read_request("read_bms_cells", id, 0x51, "read BMS block (0x1120 or 0x1540?)"));
  out.push_back(read_request("read_bms_faults", id, 0x52, "read BMS block (0x1204?)"));
  out.push_back(read_request("read_bms_nameplate", id, 0x53, "read BMS block (0x1410?)"));
  out.push_back(read_request("read_bms_temps", id, 0x54, "read BMS block (0x1810 or 0x1540?)"));
}

}  // namespace

void append_bms_messages(std::vector<MessageDesc>& out) {
  // 0x720 BMS -> all.
  out.push_back({.name = "bms_status",
                 .can_id = kBmsBroadcast,
                 .function = 0x10,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kBmsStatus,
                 .title = "BMS status"});
  out.push_back({.name = "bms_cells",
                 .can_id = kBmsBroadcast,
                 .function = 0x11,
                 .length = 32,
                 .mode = Mode::kReport,
                 .fields = kBmsCells,
                 .title = "cell voltages 1..16"});
  out.push_back(fault_word("bms_faults", kBmsBroadcast, 0x12, FaultSource::kBms,
                           "BMS alarm + protection words"));
  out.push_back(keyword_message("shutdown", kBmsBroadcast, 0x13, Mode::kReport, "SHUTDOWN",
                                "BMS-initiated power-down"));
  out.push_back({.name = "bms_nameplate",
                 .can_id = kBmsBroadcast,
                 .function = 0x14,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kBmsNameplate,
                 .title = "battery nameplate data"});
  out.push_back(model_info(kBmsBroadcast, 0x15, "BMS model info"));
  out.push_back({.name = "bms_temps",
                 .can_id = kBmsBroadcast,
                 .function = 0x18,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kBmsTemps,
                 .title = "extra temperatures / times"});

  // 0x721 BMS -> MC, 0x725 BMS -> CDL.
  out.push_back(keyword_message("ready", kBmsToMc, 0x30, Mode::kReport, "READY",
                                "BMS answer to the MC HANDSHAKE"));
  out.push_back({.name = "pack_stats",
                 .can_id = kBmsToCdl,
                 .function = 0x50,
                 .length = 40,
                 .mode = Mode::kReport,
                 .fields = kPackStats,
                 .title = "pack lifetime statistics"});

  // Reads of BMS data.
  append_block_reads(out, kObcToBms);
  append_block_reads(out, kIotToBms);
  // CDL reads; the answers (0x725/0x5028 and/or 0x720 frames) are not paired in the spec (U16).
  out.push_back(read_request("read_bms_data_33", kCdlToBms, 0x33, "CDL reads BMS data"));
  out.push_back(read_request("read_bms_data_34", kCdlToBms, 0x34, "CDL reads BMS data"));
  out.push_back(read_request("read_bms_data_35", kCdlToBms, 0x35, "CDL reads BMS data"));
  out.push_back(read_request("read_bms_data_36", kCdlToBms, 0x36, "CDL reads BMS data"));
  out.push_back(read_request("read_bms_data_38", kCdlToBms, 0x38, "CDL reads BMS data"));
}

}  // namespace motinova::detail
