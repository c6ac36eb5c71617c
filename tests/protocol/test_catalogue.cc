// The message catalogue against spec §3.1 (every V4.6.2 message, right length and mode) and
// the structural rules every table entry must obey.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "motinova/catalogue.h"
#include "motinova/codec.h"

namespace motinova {
namespace {

struct Expected {
  uint16_t can_id;
  uint8_t mode;
  uint16_t command;
};

std::string label(uint16_t id, uint16_t command) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%03X/0x%04X", id, command);
  return buf;
}

// Spec §3.1, row by row (0x751's second read is the U16 pick 0x1900).
std::vector<Expected> spec_table() {
  std::vector<Expected> t = {
      {0x710, 0x0C, 0x1020}, {0x710, 0x0C, 0x1104}, {0x710, 0x0C, 0x1240}, {0x710, 0x0C, 0x1305},
      {0x710, 0x0C, 0x1510}, {0x710, 0x0C, 0x1720}, {0x712, 0x11, 0x3009}, {0x713, 0x11, 0x5009},
      {0x713, 0x0C, 0x5303}, {0x713, 0x0C, 0x5408}, {0x713, 0x0C, 0x5510}, {0x713, 0x0C, 0x5620},
      {0x715, 0x0C, 0xA230}, {0x715, 0x0C, 0xAC10}, {0x720, 0x0C, 0x1010}, {0x720, 0x0C, 0x1120},
      {0x720, 0x0C, 0x1204}, {0x720, 0x0C, 0x1308}, {0x720, 0x0C, 0x1410}, {0x720, 0x0C, 0x1540},
      {0x720, 0x0C, 0x1810}, {0x721, 0x0C, 0x3005}, {0x725, 0x0C, 0x5028}, {0x730, 0x0C, 0x1008},
      {0x730, 0x0C, 0x1140}, {0x730, 0x0C, 0x1405}, {0x730, 0x0C, 0x1504}, {0x731, 0x0C, 0x3002},
      {0x731, 0x0C, 0x3105}, {0x731, 0x11, 0x3300}, {0x731, 0x16, 0x3408}, {0x731, 0x11, 0x3500},
      {0x731, 0x16, 0x3605}, {0x731, 0x11, 0x3900}, {0x731, 0x16, 0x4008}, {0x731, 0x11, 0x4100},
      {0x731, 0x16, 0x4208}, {0x731, 0x11, 0x4300}, {0x731, 0x16, 0x4420}, {0x732, 0x11, 0x5000},
      {0x732, 0x11, 0x5100}, {0x732, 0x11, 0x5200}, {0x732, 0x11, 0x5300}, {0x732, 0x11, 0x5400},
      {0x735, 0x0C, 0x9003}, {0x735, 0x0C, 0x9310}, {0x751, 0x11, 0x1200}, {0x751, 0x11, 0x1900},
      {0x752, 0x11, 0x3300}, {0x752, 0x11, 0x3400}, {0x752, 0x11, 0x3500}, {0x752, 0x11, 0x3600},
      {0x752, 0x11, 0x3800}, {0x753, 0x11, 0x5400}, {0x753, 0x11, 0x5600}, {0x760, 0x0C, 0x1008},
      {0x760, 0x0C, 0x1104}, {0x760, 0x0C, 0x1206}, {0x760, 0x0C, 0x1340}, {0x760, 0x0C, 0x1405},
      {0x760, 0x0C, 0x1504}, {0x761, 0x16, 0x3002}, {0x761, 0x0C, 0x3105}, {0x761, 0x11, 0x3300},
      {0x761, 0x16, 0x3408}, {0x761, 0x11, 0x3500}, {0x761, 0x16, 0x3605}, {0x761, 0x11, 0x3900},
      {0x761, 0x11, 0x4300}, {0x761, 0x16, 0x4420}, {0x762, 0x11, 0x5000}, {0x762, 0x11, 0x5100},
      {0x762, 0x11, 0x5200}, {0x762, 0x11, 0x5300}, {0x762, 0x11, 0x5400}, {0x763, 0x11, 0x7000},
      {0x763, 0x16, 0x7008},
  };
  // Locks: commands on 0x767..0x76B, broadcasts on 0x770..0x7B0.
  for (int k = 0; k < 5; ++k) {
    const auto cmd = static_cast<uint16_t>(0x767 + k);
    const auto bc = static_cast<uint16_t>(0x770 + 0x10 * k);
    const auto f = static_cast<uint16_t>(0x80 + 0x10 * k);
    t.push_back({cmd, 0x11, static_cast<uint16_t>(f << 8)});
    t.push_back({cmd, 0x11, static_cast<uint16_t>((f + 1) << 8)});
    t.push_back({cmd, 0x16, static_cast<uint16_t>((f + 2) << 8 | 4)});
    t.push_back({cmd, 0x16, static_cast<uint16_t>((f + 3) << 8 | 6)});
    t.push_back({bc, 0x0C, 0x1010});
    t.push_back({bc, 0x0C, 0x1104});
    t.push_back({bc, 0x0C, 0x1240});
  }
  return t;
}

const Catalogue& cat() {
  return Catalogue::standard();
}

TEST(Catalogue, EveryV462MessageOfSection31IsPresentWithLengthAndMode) {
  for (const Expected& e : spec_table()) {
    const auto function = static_cast<uint8_t>(e.command >> 8);
    const auto length = static_cast<uint8_t>(e.command & 0xFF);
    const MessageDesc* m = cat().find(e.can_id, function, length);
    ASSERT_NE(m, nullptr) << label(e.can_id, e.command) << " missing";
    EXPECT_EQ(m->command(), e.command) << label(e.can_id, e.command);
    EXPECT_EQ(static_cast<uint8_t>(m->mode), e.mode) << label(e.can_id, e.command);
    EXPECT_EQ(m->version, SpecVersion::kV462) << label(e.can_id, e.command);
  }
}

TEST(Catalogue, HoldsNoV462MessageBeyondSection31) {
  std::set<std::pair<uint16_t, uint16_t>> expected;
  for (const Expected& e : spec_table()) expected.insert({e.can_id, e.command});
  std::size_t v462 = 0;
  for (const MessageDesc& m : cat().messages()) {
    if (m.version != SpecVersion::kV462) continue;
    ++v462;
    EXPECT_TRUE(expected.count({m.can_id, m.command()})) << label(m.can_id, m.command());
  }
  EXPECT_EQ(v462, expected.size());
}

TEST(Catalogue, NoDuplicateIdFunctionLength) {
  std::set<std::tuple<uint16_t, uint8_t, uint8_t>> seen;
  std::map<std::pair<uint16_t, uint8_t>, int> per_function;
  for (const MessageDesc& m : cat().messages()) {
    EXPECT_TRUE(seen.insert({m.can_id, m.function, m.length}).second)
        << label(m.can_id, m.command());
    ++per_function[{m.can_id, m.function}];
  }
  // The spec reuses a function code on one ID exactly once: 0x763 read 0x7000 / SHUTDOWN 0x7008.
  for (const auto& [key, n] : per_function) {
    if (key == std::pair<uint16_t, uint8_t>{0x763, 0x70}) {
      EXPECT_EQ(n, 2);
    } else {
      EXPECT_EQ(n, 1) << label(key.first, static_cast<uint16_t>(key.second << 8));
    }
  }
}

TEST(Catalogue, NamesAreUniquePerIdAndSnakeCase) {
  std::set<std::pair<uint16_t, std::string_view>> seen;
  for (const MessageDesc& m : cat().messages()) {
    EXPECT_TRUE(seen.insert({m.can_id, m.name}).second)
        << m.name << " twice on " << label(m.can_id, m.command());
    for (char c : m.name) {
      EXPECT_TRUE((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_') << m.name;
    }
    EXPECT_FALSE(m.title.empty()) << m.name;
  }
}

// Every byte of DATA belongs to exactly one field (reserved bytes included), so the layout adds
// up to n. The only overlap allowed is a masked boolean on a byte also exposed as flags.
TEST(Catalogue, FieldsLieInsideDataAndCoverItExactlyOnce) {
  for (const MessageDesc& m : cat().messages()) {
    SCOPED_TRACE(std::string(m.name) + " " + label(m.can_id, m.command()));
    EXPECT_LE(m.fields.size(), kMaxFields);
    std::vector<int> cover(m.length, 0);
    std::set<std::string_view> names;
    for (const FieldDesc& f : m.fields) {
      const unsigned count = f.kind == FieldKind::kArray ? f.count : 1;
      ASSERT_LE(f.offset + f.size * count, m.length) << f.name;
      if (f.kind != FieldKind::kReserved) {
        EXPECT_TRUE(names.insert(f.name).second) << "field " << f.name << " twice";
      }
      if (f.kind == FieldKind::kBool && f.bool_mask != 0) continue;  // overlay on flags
      for (unsigned i = 0; i < f.size * count; ++i) ++cover[f.offset + i];
    }
    for (std::size_t i = 0; i < cover.size(); ++i) {
      EXPECT_EQ(cover[i], 1) << "byte " << i;
    }
  }
}

TEST(Catalogue, MaskedBooleansSitOnAFlagsField) {
  for (const MessageDesc& m : cat().messages()) {
    for (const FieldDesc& f : m.fields) {
      if (f.kind != FieldKind::kBool || f.bool_mask == 0) continue;
      const bool on_flags = std::any_of(m.fields.begin(), m.fields.end(), [&](const auto& g) {
        return g.kind == FieldKind::kFlags && g.offset == f.offset && g.size == f.size;
      });
      EXPECT_TRUE(on_flags) << m.name << "." << f.name;
    }
  }
}

TEST(Catalogue, KindsAreConsistent) {
  for (const MessageDesc& m : cat().messages()) {
    SCOPED_TRACE(std::string(m.name) + " " + label(m.can_id, m.command()));
    switch (m.kind) {
      case MessageKind::kKeyword:
        EXPECT_EQ(m.keyword.size(), m.length);
        ASSERT_EQ(m.fields.size(), 1u);
        EXPECT_EQ(m.fields[0].kind, FieldKind::kAscii);
        break;
      case MessageKind::kModelInfo:
        EXPECT_EQ(m.name, "device_info");
        EXPECT_EQ(m.length, 64);
        ASSERT_EQ(m.fields.size(), 4u);
        EXPECT_EQ(m.fields[0].name, "model");
        EXPECT_EQ(m.fields[1].name, "serial");
        EXPECT_EQ(m.fields[2].name, "hw");
        EXPECT_EQ(m.fields[3].name, "fw");
        break;
      case MessageKind::kFaultWord:
        EXPECT_EQ(m.length, 4);
        ASSERT_EQ(m.fields.size(), 1u);
        EXPECT_EQ(m.fields[0].name, "raw");
        EXPECT_EQ(m.fields[0].kind, FieldKind::kFaultWord);
        break;
      case MessageKind::kData:
        EXPECT_EQ(m.length == 0, m.fields.empty());
        break;
    }
  }
}

TEST(Catalogue, KeywordMessagesAreNamedAfterTheirKeyword) {
  std::map<std::string_view, std::string_view> expected = {{"READY", "ready"},
                                                           {"LOCK", "lock"},
                                                           {"UNLOCK", "unlock"},
                                                           {"SHUTDOWN", "shutdown"},
                                                           {"HANDSHAKE", "handshake"},
                                                           {"CLEAR", "clear"},
                                                           {"ACK", "ack"},
                                                           {"SET", "set"},
                                                           {"STAR", "start"}};
  int count = 0;
  for (const MessageDesc& m : cat().messages()) {
    if (m.kind != MessageKind::kKeyword) continue;
    ++count;
    ASSERT_TRUE(expected.count(m.keyword)) << m.keyword;
    EXPECT_EQ(m.name, expected[m.keyword]) << label(m.can_id, m.command());
  }
  EXPECT_GT(count, 30);
}

TEST(Catalogue, FaultWordsNameTheirSource) {
  const std::map<std::string_view, FaultSource> expected = {
      {"mc_faults", FaultSource::kMc},     {"bms_faults", FaultSource::kBms},
      {"obc_faults", FaultSource::kObc},   {"iot_faults", FaultSource::kIot},
      {"lock_faults", FaultSource::kLock}, {"hmi_faults", FaultSource::kHmi}};
  std::set<std::string_view> seen;
  for (const MessageDesc& m : cat().messages()) {
    if (m.kind != MessageKind::kFaultWord) continue;
    ASSERT_TRUE(expected.count(m.name)) << m.name;
    EXPECT_EQ(m.fault_source, expected.at(m.name)) << m.name;
    seen.insert(m.name);
  }
  EXPECT_EQ(seen.size(), expected.size());
  EXPECT_EQ(cat().find(0x7B0, 0x11)->name, "lock_faults");
}

std::vector<std::string_view> field_names(const MessageDesc& m) {
  std::vector<std::string_view> out;
  for (const FieldDesc& f : m.fields) {
    if (f.kind != FieldKind::kReserved) out.push_back(f.name);
  }
  return out;
}

using Names = std::vector<std::string_view>;

TEST(Catalogue, ProductVocabulary) {
  EXPECT_EQ(field_names(*cat().find(0x710, 0x10)), (Names{"speed_kmh",   "motor_rpm",
                                                          "power_w",     "voltage_v",
                                                          "current_a",   "cadence_rpm",
                                                          "torque_nm",   "direction",
                                                          "assist",      "headlight",
                                                          "soc_pct",     "range_km",
                                                          "odo_km",      "consumption_ah_per_km",
                                                          "pcb_temp_c",  "motor_temp_c",
                                                          "mcu_temp_c",  "trip_km",
                                                          "trip_time_s", "status_flags"}));
  EXPECT_EQ(field_names(*cat().find(0x710, 0x15)),
            (Names{"odo_km", "odo_time_min", "trip_km", "trip_time_min"}));
  EXPECT_EQ(field_names(*cat().find(0x720, 0x10)),
            (Names{"voltage_v", "current_a", "remaining_mah", "full_mah", "temp_c", "soc_pct",
                   "charging", "state_flags", "soh_pct", "cycles", "charge_time_min"}));
  EXPECT_EQ(field_names(*cat().find(0x720, 0x11)), (Names{"cells_mv"}));
  EXPECT_EQ(
      field_names(*cat().find(0x725, 0x50)),
      (Names{"max_temp_c", "min_temp_c", "max_discharge_current_a", "max_charge_current_a",
             "cycles", "charge_time_total_h", "charge_time_longest_h", "over_charge_count",
             "over_discharge_count", "charge_over_current_count", "discharge_over_current_count",
             "short_circuit_count", "charge_over_temp_count", "charge_under_temp_count",
             "discharge_over_temp_count", "discharge_under_temp_count", "runtime_min", "soh_pct"}));
  const Names lock = {"voltage_v", "current_a", "temp_c", "state", "bolts"};
  for (uint16_t id : {0x770, 0x780, 0x790, 0x7B0}) {
    EXPECT_EQ(field_names(*cat().find(id, 0x10)), lock) << label(id, 0x1010);
  }
  Names lock4 = lock;
  lock4.push_back("motor_rpm");
  EXPECT_EQ(field_names(*cat().find(0x7A0, 0x10)), lock4);

  const MessageDesc& mc = *cat().find(0x710, 0x10);
  EXPECT_EQ(mc.name, "mc_status");
  const auto quirk = [&](std::string_view name) {
    for (const FieldDesc& f : mc.fields) {
      if (f.name == name) return f.quirk;
    }
    return Quirk::kNone;
  };
  EXPECT_EQ(quirk("voltage_v"), Quirk::kMcVoltage);
  EXPECT_EQ(quirk("current_a"), Quirk::kMcCurrent);
  EXPECT_EQ(quirk("assist"), Quirk::kAssist);
  EXPECT_EQ(cat().find(0x761, 0x34)->name, "write_mc_settings");
  EXPECT_EQ(cat().find(0x761, 0x30)->name, "set_assist");
}

TEST(Catalogue, LookupByNameAndId) {
  const MessageDesc* unlock = cat().find("unlock", 0x769);
  ASSERT_NE(unlock, nullptr);
  EXPECT_EQ(unlock->command(), 0xA306);
  EXPECT_EQ(unlock->keyword, "UNLOCK");
  EXPECT_EQ(cat().find("unlock", 0x710), nullptr);
  EXPECT_EQ(cat().find(0x710, 0x99), nullptr);
  EXPECT_EQ(cat().find(0x710, 0x10, 31), nullptr);  // known function, other length
  EXPECT_NE(cat().find(0x710, 0x10), nullptr);
  EXPECT_EQ(cat().find(0x763, 0x70, 0)->name, "read_obc_info");
  EXPECT_EQ(cat().find(0x763, 0x70, 8)->name, "shutdown");
}

TEST(Catalogue, V30MessagesAreMarked) {
  struct V30 {
    uint16_t id;
    uint16_t command;
    std::string_view name;
  };
  for (const V30& e :
       {V30{0x710, 0x1401, "mc_comm_status"}, V30{0x710, 0x1608, "mc_angles"},
        V30{0x720, 0x160C, "bms_id"}, V30{0x720, 0x170C, "bms_key"}, V30{0x730, 0x120C, "obc_id"},
        V30{0x730, 0x130C, "obc_key"}, V30{0x740, 0x1040, "device_info"},
        V30{0x740, 0x1305, "ready"}, V30{0x740, 0x1404, "hmi_faults"},
        V30{0x715, 0xAB88, "memory_dump"}, V30{0x735, 0x9910, "obc_settings"}}) {
    const MessageDesc* m = cat().find(e.id, static_cast<uint8_t>(e.command >> 8),
                                      static_cast<uint8_t>(e.command & 0xFF));
    ASSERT_NE(m, nullptr) << label(e.id, e.command);
    EXPECT_EQ(m->name, e.name);
    EXPECT_EQ(m->version, SpecVersion::kV30);
  }
}

TEST(Catalogue, ConstructorRejectsDuplicatesNamingBoth) {
  std::vector<MessageDesc> twice = {
      {.name = "first", .can_id = 0x710, .function = 0x10, .length = 0, .mode = Mode::kReport},
      {.name = "second", .can_id = 0x710, .function = 0x10, .length = 0, .mode = Mode::kReport},
  };
  try {
    Catalogue c(twice);
    FAIL() << "duplicate accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("first"), std::string::npos) << what;
    EXPECT_NE(what.find("second"), std::string::npos) << what;
    EXPECT_NE(what.find("0x710/0x1000"), std::string::npos) << what;
  }
}

TEST(Catalogue, ConstructorRejectsFieldBeyondData) {
  static constexpr FieldDesc kTooLong[] = {{.name = "wide", .offset = 1, .size = 2}};
  std::vector<MessageDesc> bad = {{.name = "short_msg",
                                   .can_id = 0x720,
                                   .function = 0x10,
                                   .length = 2,
                                   .mode = Mode::kReport,
                                   .fields = kTooLong}};
  try {
    Catalogue c(bad);
    FAIL() << "field beyond DATA accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("short_msg"), std::string::npos) << what;
    EXPECT_NE(what.find("'wide'"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace motinova
