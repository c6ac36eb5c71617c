// Internal to the protocol library: the per-node message tables that make up
// Catalogue::standard(), and the small helpers they share.
//
// Contract: every append_* function adds MessageDesc values whose `fields` spans point at
// static constexpr arrays (program lifetime), so the descriptors may be copied freely. The
// tables hold no state; calling a function twice appends the same entries twice (the
// Catalogue constructor would then reject the duplicates).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "motinova/catalogue.h"

namespace motinova::detail {

void append_mc_messages(std::vector<MessageDesc>& out);       // catalogue_mc.cc
void append_bms_messages(std::vector<MessageDesc>& out);      // catalogue_bms.cc
void append_obc_iot_messages(std::vector<MessageDesc>& out);  // catalogue_obc_iot.cc
void append_lock_messages(std::vector<MessageDesc>& out);     // catalogue_locks.cc
void append_v30_messages(std::vector<MessageDesc>& out);      // catalogue_v30.cc

// Temperatures are u8 with a +40 °C offset (spec §3.0).
inline constexpr double kTempBias = -40.0;

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
// The 64-byte MODEL[16] SN[16] HW[16] FW[16] block (spec §3.0), shared by every node.
inline constexpr FieldDesc kModelInfoFields[] = {
    {.name = "model", .offset = 0, .size = 16, .kind = FieldKind::kAscii},
    {.name = "serial", .offset = 16, .size = 16, .kind = FieldKind::kAscii},
    {.name = "hw", .offset = 32, .size = 16, .kind = FieldKind::kAscii},
    {.name = "fw", .offset = 48, .size = 16, .kind = FieldKind::kAscii},
};

// A fault word is exposed as one normalised 32-bit value; faults.h names its bits.
inline constexpr FieldDesc kFaultWordFields[] = {
    {.name = "raw", .offset = 0, .size = 4, .kind = FieldKind::kFaultWord},
};

// Keyword messages expose their text as one ASCII field spanning the whole DATA.
template <uint8_t N>
inline constexpr FieldDesc kKeywordFields[] = {
    {.name = "keyword", .offset = 0, .size = N, .kind = FieldKind::kAscii},
};

// Layouts sent by both the OBC (0x731) and the IOT (0x761) to the MC, so they are shared.

// 0x3002 assist level + headlight (spec §3.4.2).
inline constexpr FieldDesc kAssistLightFields[] = {
    {.name = "assist", .offset = 0, .kind = FieldKind::kEnum, .quirk = Quirk::kAssist},
    {.name = "headlight", .offset = 1, .kind = FieldKind::kBool, .true_raw = 0xF1, .false_raw = 0xF0},
};

// 0x3408 write MC settings (spec §3.4.3). Offset 4 is the remote speed-limit function.
inline constexpr FieldDesc kWriteMcSettingsFields[] = {
    {.name = "wheel_adjust_cm", .offset = 0, .kind = FieldKind::kSigned, .quirk = Quirk::kWheelAdjust, .unit = "cm"},
    {.name = "mode", .offset = 1},
    {.name = "reserved", .offset = 2, .size = 2, .kind = FieldKind::kReserved},
    {.name = "speed_limit_offset_kmh", .offset = 4, .kind = FieldKind::kSigned, .unit = "km/h"},
    {.name = "reserved", .offset = 5, .size = 3, .kind = FieldKind::kReserved},
};

// 0x5620 report / 0x4420 write: assist tuning, raw value = percent of nominal (spec §3.2.10).
inline constexpr FieldDesc kAssistTuningFields[] = {
    {.name = "eco_ratio_gain_pct", .offset = 0, .unit = "%"},
    {.name = "eco_response_gain_pct", .offset = 1, .unit = "%"},
    {.name = "norm_ratio_gain_pct", .offset = 2, .unit = "%"},
    {.name = "norm_response_gain_pct", .offset = 3, .unit = "%"},
    {.name = "sport_ratio_gain_pct", .offset = 4, .unit = "%"},
    {.name = "sport_response_gain_pct", .offset = 5, .unit = "%"},
    {.name = "turbo_ratio_gain_pct", .offset = 6, .unit = "%"},
    {.name = "turbo_response_gain_pct", .offset = 7, .unit = "%"},
    {.name = "smart_ratio_gain_pct", .offset = 8, .unit = "%"},
    {.name = "smart_response_gain_pct", .offset = 9, .unit = "%"},
    {.name = "eco_current_gain_pct", .offset = 10, .unit = "%"},
    {.name = "eco_torque_gain_pct", .offset = 11, .unit = "%"},
    {.name = "norm_current_gain_pct", .offset = 12, .unit = "%"},
    {.name = "norm_torque_gain_pct", .offset = 13, .unit = "%"},
    {.name = "sport_current_gain_pct", .offset = 14, .unit = "%"},
    {.name = "sport_torque_gain_pct", .offset = 15, .unit = "%"},
    {.name = "turbo_current_gain_pct", .offset = 16, .unit = "%"},
    {.name = "turbo_torque_gain_pct", .offset = 17, .unit = "%"},
    {.name = "smart_current_gain_pct", .offset = 18, .unit = "%"},
    {.name = "smart_torque_gain_pct", .offset = 19, .unit = "%"},
    {.name = "reserved", .offset = 20, .size = 12, .kind = FieldKind::kReserved},
};
// clang-format on

std::span<const FieldDesc> keyword_fields(std::size_t length);  // catalogue.cc

// Builders for the message shapes that repeat on many IDs. Data messages are written out in
// full with designated initialisers in the per-node files.
MessageDesc keyword_message(std::string_view name, uint16_t can_id, uint8_t function, Mode mode,
                            std::string_view keyword, std::string_view title,
                            SpecVersion version = SpecVersion::kV462);
MessageDesc read_request(std::string_view name, uint16_t can_id, uint8_t function,
                         std::string_view title, SpecVersion version = SpecVersion::kV462);
MessageDesc model_info(uint16_t can_id, uint8_t function, std::string_view title,
                       SpecVersion version = SpecVersion::kV462);
MessageDesc fault_word(std::string_view name, uint16_t can_id, uint8_t function, FaultSource source,
                       std::string_view title, SpecVersion version = SpecVersion::kV462);

}  // namespace motinova::detail
