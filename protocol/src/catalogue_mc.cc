// MC (node 1) messages of V4.6.2: broadcasts on 0x710, requests to the BMS (0x712) and the
// OBC (0x713), lifetime records for the CDL (0x715), and the CDL's reads of them (0x751).
// Spec §3.1 and §3.2. One line per field; tags in comments are the spec's confidence marks.

#include "catalogue_tables.h"

namespace motinova::detail {
namespace {

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
constexpr EnumEntry kDirectionNames[] = {
    {0, "forward"},
    {1, "reverse"},
    {2, "stationary"},
};

// 0x710/0x1020 MC running data (§3.2.1). Voltage and current positions depend on U9, the
// current's signedness on U4, assist names on U7.
constexpr FieldDesc kMcStatus[] = {
    {.name = "speed_kmh", .offset = 0, .size = 2, .scale = 0.1, .unit = "km/h"},
    {.name = "motor_rpm", .offset = 2, .size = 2, .unit = "rpm"},
    {.name = "power_w", .offset = 4, .size = 2, .unit = "W"},
    {.name = "voltage_v", .offset = 6, .size = 2, .scale = 0.001, .quirk = Quirk::kMcVoltage, .unit = "V"},
    {.name = "current_a", .offset = 8, .size = 2, .scale = 0.001, .quirk = Quirk::kMcCurrent, .unit = "A"},
    {.name = "cadence_rpm", .offset = 10, .unit = "rpm"},
    {.name = "torque_nm", .offset = 11, .unit = "N·m"},
    {.name = "direction", .offset = 12, .kind = FieldKind::kEnum, .enum_names = kDirectionNames},
    {.name = "assist", .offset = 13, .kind = FieldKind::kEnum, .enum_style = EnumStyle::kRawThenName, .quirk = Quirk::kAssist},
    {.name = "headlight", .offset = 14, .kind = FieldKind::kBool, .true_raw = 0xF1, .false_raw = 0xF0},
    {.name = "soc_pct", .offset = 15, .invalid_raw = 0xFF, .unit = "%"},
    {.name = "range_km", .offset = 16, .size = 2, .invalid_raw = 0xFFFF, .unit = "km"},
    {.name = "odo_km", .offset = 18, .size = 2, .unit = "km"},
    {.name = "consumption_ah_per_km", .offset = 20, .scale = 0.01, .invalid_raw = 0xFF, .unit = "Ah/km"},
    {.name = "pcb_temp_c", .offset = 21, .bias = kTempBias, .unit = "°C"},
    {.name = "motor_temp_c", .offset = 22, .bias = kTempBias, .unit = "°C"},
    {.name = "mcu_temp_c", .offset = 23, .bias = kTempBias, .unit = "°C"},
    {.name = "trip_km", .offset = 24, .size = 2, .scale = 0.1, .unit = "km"},
    {.name = "trip_time_s", .offset = 26, .size = 2, .unit = "s"},
    {.name = "reserved", .offset = 28, .size = 3, .kind = FieldKind::kReserved},
    {.name = "status_flags", .offset = 31, .kind = FieldKind::kFlags},  // U8: meanings unknown
};

// 0x710/0x1510 distance/time totals (§3.2.5) [C].
constexpr FieldDesc kMcOdometer[] = {
    {.name = "odo_km", .offset = 0, .size = 4, .scale = 0.1, .unit = "km"},
    {.name = "odo_time_min", .offset = 4, .size = 4, .unit = "min"},
    {.name = "trip_km", .offset = 8, .size = 4, .scale = 0.1, .unit = "km"},
    {.name = "trip_time_min", .offset = 12, .size = 4, .unit = "min"},
};

// 0x710/0x1720 32-byte ASCII string, title illegible (§3.2.6, U10).
constexpr FieldDesc kMcString[] = {
    {.name = "text", .offset = 0, .size = 32, .kind = FieldKind::kAscii},
};

// 0x713/0x5408 MC settings report (§3.2.8), U11 for units and mode names.
constexpr FieldDesc kMcSettings[] = {
    {.name = "wheel_size_cm", .offset = 0, .quirk = Quirk::kWheelSize, .unit = "cm"},
    {.name = "mode", .offset = 1},
    {.name = "speed_limit_kmh", .offset = 2, .unit = "km/h"},
    {.name = "wheel_adjust_cm", .offset = 3, .kind = FieldKind::kSigned, .quirk = Quirk::kWheelAdjust, .unit = "cm"},
    {.name = "reserved", .offset = 4, .size = 2, .kind = FieldKind::kReserved},
    {.name = "speed_limit_offset_kmh", .offset = 6, .kind = FieldKind::kSigned, .unit = "km/h"},
    {.name = "reserved", .offset = 7, .size = 1, .kind = FieldKind::kReserved},
};

// 0x713/0x5510 MC parameter block 2 (§3.2.9), names U11.
constexpr FieldDesc kMcParams2[] = {
    {.name = "selector", .offset = 0},
    {.name = "p1", .offset = 1},
    {.name = "p2", .offset = 2},
    {.name = "p3", .offset = 3},
    {.name = "p4_min", .offset = 4, .unit = "min"},
    {.name = "p5", .offset = 5},
    {.name = "reserved", .offset = 6, .size = 10, .kind = FieldKind::kReserved},
};

// 0x715/0xA230 MC lifetime record 1 (§3.2.11): counters in low-word fault-bit order.
constexpr FieldDesc kMcLifetime1[] = {
    {.name = "power_on_count", .offset = 0, .size = 4},
    {.name = "operating_time_min", .offset = 4, .size = 4, .unit = "min"},
    {.name = "over_current_count", .offset = 8, .size = 2},
    {.name = "under_voltage_count", .offset = 10, .size = 2},
    {.name = "over_voltage_count", .offset = 12, .size = 2},
    {.name = "rotor_locked_count", .offset = 14, .size = 2},
    {.name = "over_heat_count", .offset = 16, .size = 2},
    {.name = "speed_sensor_fault_count", .offset = 18, .size = 2},
    {.name = "torque_sensor_fault_count", .offset = 20, .size = 2},
    {.name = "hall_or_brake_fault_count", .offset = 22, .size = 2},  // low bit 0x0080, U6
    {.name = "phase_line_fault_count", .offset = 24, .size = 2},  // low bit 0x0100, U6
    {.name = "ntc_fault_count", .offset = 26, .size = 2},
    {.name = "bms_check_fault_count", .offset = 28, .size = 2},
    {.name = "hmi_check_fault_count", .offset = 30, .size = 2},
    {.name = "pbu_check_fault_count", .offset = 32, .size = 2},
    {.name = "pcb_temp_max_c", .offset = 34, .bias = kTempBias, .unit = "°C"},
    {.name = "pcb_temp_min_c", .offset = 35, .bias = kTempBias, .unit = "°C"},
    {.name = "reserved", .offset = 36, .size = 4, .kind = FieldKind::kReserved},
    {.name = "motor_temp_max_c", .offset = 40, .bias = kTempBias, .unit = "°C"},
    {.name = "motor_temp_min_c", .offset = 41, .bias = kTempBias, .unit = "°C"},
    {.name = "mcu_temp_max_c", .offset = 42, .bias = kTempBias, .unit = "°C"},
    {.name = "mcu_temp_min_c", .offset = 43, .bias = kTempBias, .unit = "°C"},
    {.name = "reserved", .offset = 44, .size = 4, .kind = FieldKind::kReserved},
};

// 0x715/0xAC10 MC lifetime record 2 (§3.2.12) [L]: counters continuing the bit order.
constexpr FieldDesc kMcLifetime2[] = {
    {.name = "mcu_fault_count", .offset = 0, .size = 2},
    {.name = "cadence_sensor_fault_count", .offset = 2, .size = 2},  // low 0x4000, U6
    {.name = "throttle_sensor_fault_count", .offset = 4, .size = 2},  // low 0x8000, U6
    {.name = "mos_short_count", .offset = 6, .size = 2},
    {.name = "bus_voltage_fault_count", .offset = 8, .size = 2},  // high 0x0002, U6
    {.name = "circuit_fault_count", .offset = 10, .size = 2},  // high 0x0004, U6
    {.name = "te_mcu_fault_count", .offset = 12, .size = 2},
    {.name = "te_circuit_fault_count", .offset = 14, .size = 2},
};
// clang-format on

constexpr uint16_t kMcBroadcast = 0x710;
constexpr uint16_t kMcToBms = 0x712;
constexpr uint16_t kMcToObc = 0x713;
constexpr uint16_t kMcToCdl = 0x715;
constexpr uint16_t kCdlToMc = 0x751;

}  // namespace

void append_mc_messages(std::vector<MessageDesc>& out) {
  // 0x710 MC -> all.
  out.push_back({.name = "mc_status",
                 .can_id = kMcBroadcast,
                 .function = 0x10,
                 .length = 32,
                 .mode = Mode::kReport,
                 .fields = kMcStatus,
                 .title = "MC running data"});
  out.push_back(fault_word("mc_faults", kMcBroadcast, 0x11, FaultSource::kMc, "MC fault words"));
  out.push_back(model_info(kMcBroadcast, 0x12, "MC model info"));
  out.push_back(keyword_message("ready", kMcBroadcast, 0x13, Mode::kReport, "READY",
                                "MC ready for power-off (reply to SHUTDOWN)"));
  out.push_back({.name = "mc_odometer",
                 .can_id = kMcBroadcast,
                 .function = 0x15,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kMcOdometer,
                 .title = "ODO / trip totals"});
  out.push_back({.name = "mc_string",
                 .can_id = kMcBroadcast,
                 .function = 0x17,
                 .length = 32,
                 .mode = Mode::kReport,
                 .fields = kMcString,
                 .title = "MC ASCII string, title illegible (U10)"});

  // 0x712 MC -> BMS, 0x713 MC -> OBC.
  out.push_back(keyword_message("handshake", kMcToBms, 0x30, Mode::kRead, "HANDSHAKE",
                                "MC start-up check of the BMS"));
  out.push_back(keyword_message("handshake", kMcToObc, 0x50, Mode::kRead, "HANDSHAKE",
                                "MC start-up check of the OBC"));
  out.push_back(
      keyword_message("ack", kMcToObc, 0x53, Mode::kReport, "ACK", "MC confirms an OBC write"));
  out.push_back({.name = "mc_settings",
                 .can_id = kMcToObc,
                 .function = 0x54,
                 .length = 8,
                 .mode = Mode::kReport,
                 .fields = kMcSettings,
                 .title = "MC settings (answer to read 0x3300)"});
  out.push_back({.name = "mc_params2",
                 .can_id = kMcToObc,
                 .function = 0x55,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kMcParams2,
                 .title = "MC parameter block 2 (answer to read 0x3900 / 0x4100)"});
  out.push_back({.name = "mc_assist_tuning",
                 .can_id = kMcToObc,
                 .function = 0x56,
                 .length = 32,
                 .mode = Mode::kReport,
                 .fields = kAssistTuningFields,
                 .title = "assist tuning table (answer to read 0x4300)"});

  // 0x715 MC -> CDL.
  out.push_back({.name = "mc_lifetime_1",
                 .can_id = kMcToCdl,
                 .function = 0xA2,
                 .length = 48,
                 .mode = Mode::kReport,
                 .fields = kMcLifetime1,
                 .title = "MC lifetime record 1 (answer to CDL 0x1200)"});
  out.push_back({.name = "mc_lifetime_2",
                 .can_id = kMcToCdl,
                 .function = 0xAC,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kMcLifetime2,
                 .title = "MC lifetime record 2, fault counters"});

  // 0x751 CDL -> MC reads. The second read's function is OCR "0xipoo": 0x1900 or 0x1D00 (U16).
  out.push_back(read_request("read_mc_lifetime_1", kCdlToMc, 0x12, "CDL reads MC lifetime 1"));
  out.push_back(read_request("read_mc_lifetime_2", kCdlToMc, 0x19,
                             "CDL reads MC lifetime 2 (function uncertain, U16)"));
}

}  // namespace motinova::detail
