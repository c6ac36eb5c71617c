// OBC (node 3) and IOT (node 6, this gateway) messages of V4.6.2: their broadcasts (0x730,
// 0x760), their commands to the MC (0x731, 0x761) and the OBC (0x763), the OBC's records for
// the CDL (0x735) and the CDL's reads of the OBC (0x753). Spec §3.1, §3.4 and §3.5. The IOT's
// commands to the locks are in catalogue_locks.cc; its BMS reads in catalogue_bms.cc.

#include "catalogue_tables.h"

namespace motinova::detail {
namespace {

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
// 0x731/0x4008 write working mode + parameter (§3.4.5, U8).
constexpr FieldDesc kWriteMcMode[] = {
    {.name = "mode_flags", .offset = 0, .kind = FieldKind::kFlags},
    {.name = "mode_param", .offset = 1},
    {.name = "reserved", .offset = 2, .size = 6, .kind = FieldKind::kReserved},
};

// 0x731/0x4208 write parameter block 2 (§3.4.5), the same values as 0x5510 (U11).
constexpr FieldDesc kWriteMcParams2[] = {
    {.name = "p1", .offset = 0},
    {.name = "p2", .offset = 1},
    {.name = "p3", .offset = 2},
    {.name = "p4_min", .offset = 3, .unit = "min"},
    {.name = "reserved", .offset = 4, .size = 4, .kind = FieldKind::kReserved},
};

// 0x735/0x9310 OBC lifetime record (§3.4.6) [L].
constexpr FieldDesc kObcLifetime[] = {
    {.name = "operating_time_min", .offset = 0, .size = 4, .unit = "min"},
    {.name = "power_on_count", .offset = 4, .size = 4},
    {.name = "reserved", .offset = 8, .size = 8, .kind = FieldKind::kReserved},
};
// clang-format on

constexpr uint16_t kObcBroadcast = 0x730;
constexpr uint16_t kObcToMc = 0x731;
constexpr uint16_t kObcToCdl = 0x735;
constexpr uint16_t kCdlToObc = 0x753;
constexpr uint16_t kIotBroadcast = 0x760;
constexpr uint16_t kIotToMc = 0x761;
constexpr uint16_t kIotToObc = 0x763;

}  // namespace

void append_obc_iot_messages(std::vector<MessageDesc>& out) {
  // 0x730 OBC -> all (§3.4.1).
  out.push_back(keyword_message("shutdown", kObcBroadcast, 0x10, Mode::kReport, "SHUTDOWN",
                                "user switches the system off"));
  out.push_back(model_info(kObcBroadcast, 0x11, "OBC model info"));
  out.push_back(keyword_message("ready", kObcBroadcast, 0x14, Mode::kReport, "READY",
                                "OBC ready for power-off"));
  out.push_back(
      fault_word("obc_faults", kObcBroadcast, 0x15, FaultSource::kObc, "OBC fault words"));

  // 0x731 OBC -> MC (§3.4.2 .. §3.4.5).
  out.push_back({.name = "set_assist",
                 .can_id = kObcToMc,
                 .function = 0x30,
                 .length = 2,
                 .mode = Mode::kReport,
                 .fields = kAssistLightFields,
                 .title = "assist level + light"});
  out.push_back(keyword_message("ready", kObcToMc, 0x31, Mode::kReport, "READY",
                                "OBC answer to the MC HANDSHAKE 0x5009"));
  out.push_back(read_request("read_mc_settings", kObcToMc, 0x33, "read MC settings -> 0x5408"));
  out.push_back({.name = "write_mc_settings",
                 .can_id = kObcToMc,
                 .function = 0x34,
                 .length = 8,
                 .mode = Mode::kWrite,
                 .fields = kWriteMcSettingsFields,
                 .title = "write MC settings"});
  out.push_back(read_request("read_mc_odometer", kObcToMc, 0x35, "read ODO/trip -> 0x1510 (U16)"));
  out.push_back(keyword_message("clear", kObcToMc, 0x36, Mode::kWrite, "CLEAR", "reset trip"));
  out.push_back(read_request("read_mc_params2", kObcToMc, 0x39, "read block 2 -> 0x5510 (U16)"));
  out.push_back({.name = "write_mc_mode",
                 .can_id = kObcToMc,
                 .function = 0x40,
                 .length = 8,
                 .mode = Mode::kWrite,
                 .fields = kWriteMcMode,
                 .title = "write working mode + parameter"});
  out.push_back(read_request("read_mc_params2_alt", kObcToMc, 0x41,
                             "read block 2 -> 0x5510 (U16; OCR shows mode 0x10)"));
  out.push_back({.name = "write_mc_params2",
                 .can_id = kObcToMc,
                 .function = 0x42,
                 .length = 8,
                 .mode = Mode::kWrite,
                 .fields = kWriteMcParams2,
                 .title = "write parameter block 2"});
  out.push_back(
      read_request("read_mc_assist_tuning", kObcToMc, 0x43, "read assist tuning -> 0x5620"));
  out.push_back({.name = "write_mc_assist_tuning",
                 .can_id = kObcToMc,
                 .function = 0x44,
                 .length = 32,
                 .mode = Mode::kWrite,
                 .fields = kAssistTuningFields,
                 .title = "write assist tuning"});

  // 0x735 OBC -> CDL (§3.4.6), 0x753 CDL -> OBC reads (0x5600 is OCR "0x5E00", U16).
  out.push_back(keyword_message("ack", kObcToCdl, 0x90, Mode::kReport, "ACK", "OBC ACK to CDL"));
  out.push_back({.name = "obc_lifetime",
                 .can_id = kObcToCdl,
                 .function = 0x93,
                 .length = 16,
                 .mode = Mode::kReport,
                 .fields = kObcLifetime,
                 .title = "OBC lifetime record"});
  out.push_back(read_request("read_obc_data_54", kCdlToObc, 0x54, "CDL reads OBC -> 0x9310"));
  out.push_back(read_request("read_obc_data_56", kCdlToObc, 0x56, "CDL reads OBC -> 0x9310"));

  // 0x760 IOT -> all (§3.5.1): what this gateway broadcasts.
  out.push_back(keyword_message("shutdown", kIotBroadcast, 0x10, Mode::kReport, "SHUTDOWN",
                                "IOT-initiated system power-off"));
  out.push_back(keyword_message("lock", kIotBroadcast, 0x11, Mode::kReport, "LOCK",
                                "one-touch vehicle lock"));
  out.push_back(keyword_message("unlock", kIotBroadcast, 0x12, Mode::kReport, "UNLOCK",
                                "one-touch vehicle unlock"));
  out.push_back(model_info(kIotBroadcast, 0x13, "IOT model info"));
  out.push_back(keyword_message("ready", kIotBroadcast, 0x14, Mode::kReport, "READY",
                                "IOT ready for power-off"));
  out.push_back(
      fault_word("iot_faults", kIotBroadcast, 0x15, FaultSource::kIot, "IOT fault words"));

  // 0x761 IOT -> MC (§3.5.2).
  out.push_back({.name = "set_assist",
                 .can_id = kIotToMc,
                 .function = 0x30,
                 .length = 2,
                 .mode = Mode::kWrite,
                 .fields = kAssistLightFields,
                 .title = "set assist level + light"});
  out.push_back(keyword_message("ready", kIotToMc, 0x31, Mode::kReport, "READY",
                                "IOT answer to the MC display handshake (U13)"));
  out.push_back(read_request("read_mc_settings", kIotToMc, 0x33, "read MC settings -> 0x5408"));
  out.push_back({.name = "write_mc_settings",
                 .can_id = kIotToMc,
                 .function = 0x34,
                 .length = 8,
                 .mode = Mode::kWrite,
                 .fields = kWriteMcSettingsFields,
                 .title = "write MC settings (remote speed limit)"});
  out.push_back(read_request("read_mc_odometer", kIotToMc, 0x35, "read ODO/trip -> 0x1510 (U16)"));
  out.push_back(keyword_message("clear", kIotToMc, 0x36, Mode::kWrite, "CLEAR", "reset trip"));
  out.push_back(read_request("read_mc_params2", kIotToMc, 0x39, "read block 2 -> 0x5510 (U16)"));
  out.push_back(
      read_request("read_mc_assist_tuning", kIotToMc, 0x43, "read assist tuning -> 0x5620"));
  out.push_back({.name = "write_mc_assist_tuning",
                 .can_id = kIotToMc,
                 .function = 0x44,
                 .length = 32,
                 .mode = Mode::kWrite,
                 .fields = kAssistTuningFields,
                 .title = "write assist tuning"});

  // 0x763 IOT -> OBC (§3.5.3).
  out.push_back(read_request("read_obc_info", kIotToObc, 0x70, "read OBC model info -> 0x1140"));
  // The one place where a function code carries two messages, told apart by n (0 vs 8).
  out.push_back(keyword_message("shutdown", kIotToObc, 0x70, Mode::kWrite, "SHUTDOWN",
                                "order the OBC to power off"));
}

}  // namespace motinova::detail
