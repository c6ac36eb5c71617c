// Lock messages of V4.6.2 (nodes 7..B), expanded per lock: the IOT's commands on 0x767..0x76B
// (function F = 0x80 + 0x10 * (k - 7), §3.5.4) and each lock's broadcasts on 0x7n0 (§3.6).
// Which physical lock sits at which node is a run-time option (U21), not part of the catalogue.

#include "catalogue_tables.h"

namespace motinova::detail {
namespace {

// One line per field, so that a spec correction stays a one-line change.
// clang-format off
// 0x7n0/0x1010 lock status (§3.6.1). Lock-state names are U19, bolt polarity U20.
constexpr FieldDesc kLockStatus[] = {
    {.name = "voltage_v", .offset = 0, .size = 2, .scale = 0.001, .unit = "V"},
    {.name = "current_a", .offset = 2, .size = 2, .scale = 0.001, .unit = "A"},
    {.name = "temp_c", .offset = 4, .bias = kTempBias, .unit = "°C"},
    {.name = "state", .offset = 5, .kind = FieldKind::kEnum, .enum_style = EnumStyle::kNameThenRaw, .quirk = Quirk::kLockState},
    {.name = "bolts", .offset = 6, .size = 2, .kind = FieldKind::kFlags},
    {.name = "reserved", .offset = 8, .size = 8, .kind = FieldKind::kReserved},
};

// LOCK 4 (node A, 0x7A0) alone reports a motor speed in bytes 8-9.
constexpr FieldDesc kLock4Status[] = {
    {.name = "voltage_v", .offset = 0, .size = 2, .scale = 0.001, .unit = "V"},
    {.name = "current_a", .offset = 2, .size = 2, .scale = 0.001, .unit = "A"},
    {.name = "temp_c", .offset = 4, .bias = kTempBias, .unit = "°C"},
    {.name = "state", .offset = 5, .kind = FieldKind::kEnum, .enum_style = EnumStyle::kNameThenRaw, .quirk = Quirk::kLockState},
    {.name = "bolts", .offset = 6, .size = 2, .kind = FieldKind::kFlags},
    {.name = "motor_rpm", .offset = 8, .size = 2, .unit = "rpm"},
    {.name = "reserved", .offset = 10, .size = 6, .kind = FieldKind::kReserved},
};
// clang-format on

}  // namespace

void append_lock_messages(std::vector<MessageDesc>& out) {
  for (int index = 0; index < kLockCount; ++index) {
    const Node lock = lock_node(index);
    const uint16_t command_id = make_can_id(Node::kIot, lock);
    const uint16_t broadcast_id = make_can_id(lock, Node::kBroadcast);
    const auto f = static_cast<uint8_t>(0x80 + 0x10 * index);

    // IOT -> lock k.
    out.push_back(read_request("read_lock_info", command_id, f, "read lock model info"));
    out.push_back(read_request("read_lock_status", command_id, f + 1, "read lock status"));
    out.push_back(keyword_message("lock", command_id, f + 2, Mode::kWrite, "LOCK", "lock"));
    out.push_back(keyword_message("unlock", command_id, f + 3, Mode::kWrite, "UNLOCK", "unlock"));

    // Lock k -> all.
    out.push_back({.name = "lock_status",
                   .can_id = broadcast_id,
                   .function = 0x10,
                   .length = 16,
                   .mode = Mode::kReport,
                   .fields = lock == Node::kLock4 ? std::span<const FieldDesc>(kLock4Status)
                                                  : std::span<const FieldDesc>(kLockStatus),
                   .title = "lock status"});
    out.push_back(
        fault_word("lock_faults", broadcast_id, 0x11, FaultSource::kLock, "lock fault words"));
    out.push_back(model_info(broadcast_id, 0x12, "lock model info"));
  }
}

}  // namespace motinova::detail
