// V3.0-only messages (spec §5.1, §5.2) whose layout is legible enough to decode: extra MC
// broadcasts, the 12-byte ID/key blocks, the HMI (node 4) set, PBU key traffic and the CDL-side
// records on 0x715/0x725/0x735/0x745. Every entry is marked SpecVersion::kV30. Field names of
// the CDL records are approximate in the spec [G]; the byte layouts add up to the declared n.
//
// Left out on purpose: 0x715/0xA020 MC configuration and 0x715/0xAE1A calibration (their
// legible field lists do not add up to n), 0x745/0xA110 HMI lifetime record (no layout), and
// the CDL -> node service commands on 0x751..0x754 (several reuse V4.6.2 function codes with
// other meanings; a V3.0 service tool is out of scope for the gateway).

#include "catalogue_tables.h"

namespace motinova::detail {
namespace {

constexpr SpecVersion kV30 = SpecVersion::kV30;

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
// 0x710/0x1401 MC communication status (§5.1) [L].
constexpr FieldDesc kMcCommStatus[] = {
    {.name = "comm_flags", .offset = 0, .kind = FieldKind::kFlags},
    {.name = "bms_comm_fault", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x01},
    {.name = "pbu_comm_fault", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x02},
    {.name = "hmi_comm_fault", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x04},
};

// 0x710/0x1608 four attitude/tilt angles, s16 0.1°, ±180.0° (§5.1); names illegible.
constexpr FieldDesc kMcAngles[] = {
    {.name = "angle_1_deg", .offset = 0, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
    {.name = "angle_2_deg", .offset = 2, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
    {.name = "angle_3_deg", .offset = 4, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
    {.name = "angle_4_deg", .offset = 6, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
};

// 12-byte unique ID (probably the MCU's 96-bit UID) and 12-byte key/cipher block.
constexpr FieldDesc kUid12[] = {
    {.name = "uid", .offset = 0, .size = 12, .kind = FieldKind::kBytes},
};
constexpr FieldDesc kBlock12[] = {
    {.name = "block", .offset = 0, .size = 12, .kind = FieldKind::kBytes},
};

// 0x714/0x7308 MC settings to the HMI: the V3.0 0x5408 layout (no speed-limit offset).
constexpr FieldDesc kMcSettingsV30[] = {
    {.name = "wheel_size_cm", .offset = 0, .quirk = Quirk::kWheelSize, .unit = "cm"},
    {.name = "mode", .offset = 1},
    {.name = "speed_limit_kmh", .offset = 2, .unit = "km/h"},
    {.name = "wheel_adjust_cm", .offset = 3, .kind = FieldKind::kSigned, .quirk = Quirk::kWheelAdjust, .unit = "cm"},
    {.name = "reserved", .offset = 4, .size = 4, .kind = FieldKind::kReserved},
};

// 0x715/0xA110 motor parameters (16 B) [G] names.
constexpr FieldDesc kMcMotorParams[] = {
    {.name = "rated_power_w", .offset = 0, .size = 2, .unit = "W"},
    {.name = "rated_rpm", .offset = 2, .size = 2, .unit = "rpm"},
    {.name = "phase_resistance_mohm", .offset = 4, .size = 2, .unit = "mΩ"},
    {.name = "lq_mh", .offset = 6, .size = 2, .unit = "mH"},
    {.name = "ld_mh", .offset = 8, .size = 2, .unit = "mH"},
    {.name = "back_emf_mv", .offset = 10, .size = 2, .unit = "mV"},
    {.name = "value", .offset = 12},
    {.name = "reserved", .offset = 13, .size = 3, .kind = FieldKind::kReserved},
};

// 0x715/0xA318 calibration table: 9 x u16 + max, min, average (24 B).
constexpr FieldDesc kMcCalibration[] = {
    {.name = "points", .offset = 0, .size = 2, .kind = FieldKind::kArray, .count = 9},
    {.name = "max", .offset = 18, .size = 2},
    {.name = "min", .offset = 20, .size = 2},
    {.name = "average", .offset = 22, .size = 2},
};

constexpr FieldDesc kText8[] = {
    {.name = "text", .offset = 0, .size = 8, .kind = FieldKind::kAscii},
};
constexpr FieldDesc kText16[] = {
    {.name = "text", .offset = 0, .size = 16, .kind = FieldKind::kAscii},
};

// AP (application) firmware info, 32 B: '.'-separated version, a string, YYYYMMDD date.
constexpr FieldDesc kApInfo[] = {
    {.name = "version", .offset = 0, .size = 8, .kind = FieldKind::kAscii},
    {.name = "text", .offset = 8, .size = 8, .kind = FieldKind::kAscii},
    {.name = "date", .offset = 16, .size = 8, .kind = FieldKind::kAscii},
    {.name = "reserved", .offset = 24, .size = 8, .kind = FieldKind::kReserved},
};

// 0x715/0xAA04: a 2-byte value and two 1-byte values, meanings illegible.
constexpr FieldDesc kMcRecordAa[] = {
    {.name = "value", .offset = 0, .size = 2},
    {.name = "aux_1", .offset = 2},
    {.name = "aux_2", .offset = 3},
};

constexpr FieldDesc kValue16[] = {
    {.name = "value", .offset = 0, .size = 2},
};

// Memory dump answer: start address, length (< 128, padded with 0xFF), 128 data bytes.
constexpr FieldDesc kMemoryDump[] = {
    {.name = "address", .offset = 0, .size = 4},
    {.name = "length", .offset = 4, .size = 4},
    {.name = "data", .offset = 8, .size = 128, .kind = FieldKind::kBytes},
};

// 0x715/0xAD20: two s16 angles, 0.1°, ±90.0°, an enable byte 0x55/0xAA, 27 reserved.
constexpr FieldDesc kMcAngleCalibration[] = {
    {.name = "angle_1_deg", .offset = 0, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
    {.name = "angle_2_deg", .offset = 2, .size = 2, .kind = FieldKind::kSigned, .scale = 0.1, .unit = "°"},
    {.name = "enabled", .offset = 4, .kind = FieldKind::kBool, .true_raw = 0x55, .false_raw = 0xAA},
    {.name = "reserved", .offset = 5, .size = 27, .kind = FieldKind::kReserved},
};

// 0x731/0x3208 PBU configuration: assist-level count 3..5, HMI fitted 0x55 yes / 0xAA no.
constexpr FieldDesc kPbuConfig[] = {
    {.name = "level_count", .offset = 0},
    {.name = "hmi_fitted", .offset = 1, .kind = FieldKind::kBool, .true_raw = 0x55, .false_raw = 0xAA},
    {.name = "reserved", .offset = 2, .size = 6, .kind = FieldKind::kReserved},
};

constexpr EnumEntry kPressTypes[] = {
    {1, "short"},
    {2, "long"},
};

// 0x734/0x7006 key event: key code, a value, press type, 3 reserved.
constexpr FieldDesc kKeyEvent[] = {
    {.name = "key_code", .offset = 0},
    {.name = "value", .offset = 1},
    {.name = "press_type", .offset = 2, .kind = FieldKind::kEnum, .enum_names = kPressTypes},
    {.name = "reserved", .offset = 3, .size = 3, .kind = FieldKind::kReserved},
};

// 0x735/0x9101 key states: 0 released, 1 pressed.
constexpr FieldDesc kKeyStates[] = {
    {.name = "keys", .offset = 0, .kind = FieldKind::kFlags},
    {.name = "plus_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x01},
    {.name = "minus_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x02},
    {.name = "info_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x04},
    {.name = "light_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x08},
    {.name = "walk_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x10},
    {.name = "power_key", .offset = 0, .kind = FieldKind::kBool, .bool_mask = 0x20},
};

constexpr EnumEntry kVoltageClasses[] = {
    {0, "24v"},
    {1, "36v"},
    {2, "48v"},
};

// 0x735/0x9210 PBU configuration report.
constexpr FieldDesc kPbuConfigReport[] = {
    {.name = "voltage_class", .offset = 0, .kind = FieldKind::kEnum, .enum_names = kVoltageClasses},
    {.name = "level_count", .offset = 1},
    {.name = "hmi_fitted", .offset = 2, .kind = FieldKind::kBool, .true_raw = 0x55, .false_raw = 0xAA},
    {.name = "reserved", .offset = 3, .size = 13, .kind = FieldKind::kReserved},
};

constexpr EnumEntry kSpeedUnits[] = {
    {0, "kmh"},
    {1, "mph"},
};
constexpr EnumEntry kLanguages[] = {
    {0, "chinese"},
    {1, "english"},
};

// 0x735/0x9910 OBC settings, also 0x745/0xA010 HMI settings. The three yes/no flags' encoding
// is illegible, so they stay raw.
constexpr FieldDesc kDisplaySettings[] = {
    {.name = "voltage_class", .offset = 0, .kind = FieldKind::kEnum, .enum_names = kVoltageClasses},
    {.name = "reserved", .offset = 1, .size = 1, .kind = FieldKind::kReserved},
    {.name = "mode", .offset = 2},
    {.name = "flag_1", .offset = 3},
    {.name = "flag_2", .offset = 4},
    {.name = "flag_3", .offset = 5},
    {.name = "brightness", .offset = 6},
    {.name = "speed_unit", .offset = 7, .kind = FieldKind::kEnum, .enum_names = kSpeedUnits},
    {.name = "flag_4", .offset = 8},
    {.name = "language", .offset = 9, .kind = FieldKind::kEnum, .enum_names = kLanguages},
    {.name = "reserved", .offset = 10, .size = 6, .kind = FieldKind::kReserved},
};

// 0x740/0x1508: 8 bytes, illegible.
constexpr FieldDesc kHmiData[] = {
    {.name = "data", .offset = 0, .size = 8, .kind = FieldKind::kBytes},
};

// 0x741/0x3208 HMI writes MC settings: wheel adjust s8, mode, 6 reserved.
constexpr FieldDesc kHmiWriteMcSettings[] = {
    {.name = "wheel_adjust_cm", .offset = 0, .kind = FieldKind::kSigned, .quirk = Quirk::kWheelAdjust, .unit = "cm"},
    {.name = "mode", .offset = 1},
    {.name = "reserved", .offset = 2, .size = 6, .kind = FieldKind::kReserved},
};
// clang-format on

MessageDesc data(std::string_view name, uint16_t id, uint8_t function, uint8_t length,
                 std::span<const FieldDesc> fields, std::string_view title,
                 Mode mode = Mode::kReport) {
  return {.name = name,
          .can_id = id,
          .function = function,
          .length = length,
          .mode = mode,
          .fields = fields,
          .version = kV30,
          .title = title};
}

void append_mc(std::vector<MessageDesc>& out) {
  out.push_back(data("mc_comm_status", 0x710, 0x14, 1, kMcCommStatus, "MC comm status"));
  out.push_back(data("mc_angles", 0x710, 0x16, 8, kMcAngles, "attitude / tilt angles"));

  out.push_back(read_request("read_bms_id", 0x712, 0x31, "read BMS 12-byte ID", kV30));
  out.push_back(read_request("read_bms_key", 0x712, 0x32, "read BMS 12-byte block", kV30));
  out.push_back(read_request("read_bms_data_33", 0x712, 0x33, "MC reads BMS data", kV30));
  out.push_back(read_request("read_obc_id", 0x713, 0x51, "read PBU/OBC 12-byte ID", kV30));
  out.push_back(read_request("read_obc_key", 0x713, 0x52, "read PBU/OBC 12-byte block", kV30));

  out.push_back(keyword_message("handshake", 0x714, 0x70, Mode::kRead, "HANDSHAKE",
                                "MC start-up check of the HMI", kV30));
  out.push_back(read_request("read_hmi_id", 0x714, 0x71, "read HMI 12-byte ID", kV30));
  out.push_back(read_request("read_hmi_key", 0x714, 0x72, "read HMI 12-byte block", kV30));
  out.push_back(data("mc_settings", 0x714, 0x73, 8, kMcSettingsV30, "MC settings to the HMI"));
  out.push_back(keyword_message("ack", 0x714, 0x74, Mode::kReport, "ACK", "MC ACK to HMI", kV30));

  out.push_back(data("mc_motor_params", 0x715, 0xA1, 16, kMcMotorParams, "motor parameters"));
  out.push_back(data("mc_calibration", 0x715, 0xA3, 24, kMcCalibration, "calibration table"));
  out.push_back(data("mc_text", 0x715, 0xA4, 8, kText8, "8-byte ASCII"));
  out.push_back(data("ap_info", 0x715, 0xA5, 32, kApInfo, "MC AP firmware info"));
  out.push_back(data("custom_string_1", 0x715, 0xA6, 16, kText16, "MC custom string 1"));
  out.push_back(data("custom_string_2", 0x715, 0xA7, 16, kText16, "MC custom string 2"));
  out.push_back(data("custom_string_3", 0x715, 0xA8, 16, kText16, "MC custom string 3"));
  out.push_back(keyword_message("ack", 0x715, 0xA9, Mode::kReport, "ACK", "MC ACK to CDL", kV30));
  out.push_back(data("mc_record_aa", 0x715, 0xAA, 4, kMcRecordAa, "MC record, illegible"));
  out.push_back(data("memory_dump", 0x715, 0xAB, 136, kMemoryDump, "MC memory dump"));
  out.push_back(
      data("mc_angle_calibration", 0x715, 0xAD, 32, kMcAngleCalibration, "angle calibration"));
  out.push_back(data("mc_value_af", 0x715, 0xAF, 2, kValue16, "MC 2-byte value"));
  out.push_back(data("mc_value_b0", 0x715, 0xB0, 2, kValue16, "MC 2-byte value"));
}

void append_bms(std::vector<MessageDesc>& out) {
  out.push_back(data("bms_id", 0x720, 0x16, 12, kUid12, "BMS 12-byte unique ID"));
  out.push_back(data("bms_key", 0x720, 0x17, 12, kBlock12, "BMS 12-byte block"));
  out.push_back(data("ap_info", 0x725, 0x51, 32, kApInfo, "BMS AP firmware info"));
  out.push_back(data("custom_string_1", 0x725, 0x52, 16, kText16, "BMS custom string 1"));
  out.push_back(data("custom_string_2", 0x725, 0x53, 16, kText16, "BMS custom string 2"));
  out.push_back(data("custom_string_3", 0x725, 0x54, 16, kText16, "BMS custom string 3"));
  out.push_back(keyword_message("ack", 0x725, 0x55, Mode::kReport, "ACK", "BMS ACK to CDL", kV30));
  out.push_back(data("memory_dump", 0x725, 0x56, 136, kMemoryDump, "BMS memory dump"));
}

void append_obc(std::vector<MessageDesc>& out) {
  out.push_back(data("obc_id", 0x730, 0x12, 12, kUid12, "PBU/OBC 12-byte ID"));
  out.push_back(data("obc_key", 0x730, 0x13, 12, kBlock12, "PBU/OBC 12-byte block"));
  out.push_back(data("pbu_config", 0x731, 0x32, 8, kPbuConfig, "PBU configuration", Mode::kWrite));

  out.push_back(data("key_event", 0x734, 0x70, 6, kKeyEvent, "PBU key event"));
  out.push_back(keyword_message("ack", 0x734, 0x71, Mode::kReport, "ACK", "PBU ACK to HMI", kV30));
  out.push_back(keyword_message("set", 0x734, 0x72, Mode::kWrite, "SET", "PBU SET", kV30));
  out.push_back(keyword_message("start", 0x734, 0x73, Mode::kWrite, "STAR", "PBU start", kV30));
  out.push_back(data("set_assist", 0x734, 0x74, 2, kAssistLightFields, "assist level + light"));

  out.push_back(data("key_states", 0x735, 0x91, 1, kKeyStates, "PBU key states"));
  out.push_back(data("pbu_config", 0x735, 0x92, 16, kPbuConfigReport, "PBU configuration"));
  out.push_back(data("ap_info", 0x735, 0x94, 32, kApInfo, "PBU/OBC AP firmware info"));
  out.push_back(data("custom_string_1", 0x735, 0x95, 16, kText16, "OBC custom string 1"));
  out.push_back(data("custom_string_2", 0x735, 0x96, 16, kText16, "OBC custom string 2"));
  out.push_back(data("custom_string_3", 0x735, 0x97, 16, kText16, "OBC custom string 3"));
  out.push_back(data("memory_dump", 0x735, 0x98, 136, kMemoryDump, "OBC memory dump"));
  out.push_back(data("obc_settings", 0x735, 0x99, 16, kDisplaySettings, "OBC settings"));
}

void append_hmi(std::vector<MessageDesc>& out) {
  out.push_back(model_info(0x740, 0x10, "HMI model info", kV30));
  out.push_back(data("hmi_id", 0x740, 0x11, 12, kUid12, "HMI 12-byte ID"));
  out.push_back(data("hmi_key", 0x740, 0x12, 12, kBlock12, "HMI 12-byte block"));
  out.push_back(keyword_message("ready", 0x740, 0x13, Mode::kReport, "READY",
                                "HMI ready for power-off", kV30));
  out.push_back(fault_word("hmi_faults", 0x740, 0x14, FaultSource::kHmi, "HMI faults", kV30));
  out.push_back(data("hmi_data", 0x740, 0x15, 8, kHmiData, "HMI 8-byte record, illegible"));

  out.push_back(read_request("read_mc_data_30", 0x741, 0x30, "HMI reads MC", kV30));
  out.push_back(read_request("read_mc_data_31", 0x741, 0x31, "HMI reads MC", kV30));
  out.push_back(data("write_mc_settings", 0x741, 0x32, 8, kHmiWriteMcSettings,
                     "HMI writes MC settings", Mode::kWrite));
  out.push_back(keyword_message("ready", 0x741, 0x33, Mode::kReport, "READY",
                                "HMI answer to the MC HANDSHAKE 0x7009", kV30));
  out.push_back(read_request("read_mc_trip", 0x741, 0x34, "HMI reads MC trip", kV30));
  out.push_back(keyword_message("clear", 0x741, 0x35, Mode::kWrite, "CLEAR", "reset trip", kV30));

  out.push_back(read_request("read_bms_status", 0x742, 0x50, "HMI reads BMS", kV30));
  out.push_back(read_request("read_bms_cells", 0x742, 0x51, "HMI reads BMS", kV30));

  out.push_back(read_request("read_obc_info", 0x743, 0x70, "HMI reads PBU/OBC", kV30));
  out.push_back({.name = "obc_command_71",
                 .can_id = 0x743,
                 .function = 0x71,
                 .length = 0,
                 .mode = Mode::kWrite,
                 .version = kV30,
                 .title = "HMI write to PBU, no data"});
  out.push_back(keyword_message("ack", 0x743, 0x72, Mode::kReport, "ACK", "HMI ACK to PBU", kV30));

  out.push_back(data("hmi_settings", 0x745, 0xA0, 16, kDisplaySettings, "HMI settings"));
  out.push_back(data("ap_info", 0x745, 0xA2, 32, kApInfo, "HMI AP firmware info"));
  out.push_back(data("custom_string_1", 0x745, 0xA3, 16, kText16, "HMI custom string 1"));
  out.push_back(data("custom_string_2", 0x745, 0xA4, 16, kText16, "HMI custom string 2"));
  out.push_back(data("custom_string_3", 0x745, 0xA5, 16, kText16, "HMI custom string 3"));
  out.push_back(keyword_message("ack", 0x745, 0xA6, Mode::kReport, "ACK", "HMI ACK to CDL", kV30));
  out.push_back(data("memory_dump", 0x745, 0xA7, 136, kMemoryDump, "HMI memory dump"));
}

}  // namespace

void append_v30_messages(std::vector<MessageDesc>& out) {
  append_mc(out);
  append_bms(out);
  append_obc(out);
  append_hmi(out);
}

}  // namespace motinova::detail
