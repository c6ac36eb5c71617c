// The fault table against spec §4 (every display code that has a CAN bit) and §3 (every
// documented bit), and the iteration helper including undefined bits.

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "motinova/faults.h"

namespace motinova {
namespace {

constexpr FaultSource kAllSources[] = {FaultSource::kMc,  FaultSource::kBms,  FaultSource::kObc,
                                       FaultSource::kIot, FaultSource::kLock, FaultSource::kHmi};

// Spec §4 code -> (source, normalised mask). BMS code 40 is printed without a bit and is
// therefore absent; HMI codes 80/81 are placed on the illegible bits 0x0004/0x0008 (guess).
const std::map<int, std::pair<FaultSource, uint32_t>>& spec_codes() {
  static const std::map<int, std::pair<FaultSource, uint32_t>> codes = {
      {10, {FaultSource::kMc, 0x0001}},       {11, {FaultSource::kMc, 0x0002}},
      {12, {FaultSource::kMc, 0x0004}},       {13, {FaultSource::kMc, 0x0008}},
      {14, {FaultSource::kMc, 0x0010}},       {15, {FaultSource::kMc, 0x0200}},
      {16, {FaultSource::kMc, 0x0020}},       {17, {FaultSource::kMc, 0x0040}},
      {18, {FaultSource::kMc, 0x0080}},       {19, {FaultSource::kMc, 0x0400}},
      {20, {FaultSource::kMc, 0x1000}},       {21, {FaultSource::kMc, 0x0800}},
      {22, {FaultSource::kMc, 0x0100}},       {23, {FaultSource::kMc, 0x4000}},
      {24, {FaultSource::kMc, 0x8000}},       {25, {FaultSource::kMc, 0x0001'0000}},
      {26, {FaultSource::kMc, 0x0002'0000}},  {27, {FaultSource::kMc, 0x2000}},
      {28, {FaultSource::kMc, 0x0004'0000}},  {29, {FaultSource::kMc, 0x0008'0000}},
      {30, {FaultSource::kMc, 0x0010'0000}},  {31, {FaultSource::kMc, 0x0020'0000}},
      {32, {FaultSource::kMc, 0x0040'0000}},  {33, {FaultSource::kMc, 0x0080'0000}},
      {41, {FaultSource::kBms, 0x0001'0000}}, {42, {FaultSource::kBms, 0x0002'0000}},
      {43, {FaultSource::kBms, 0x0004'0000}}, {44, {FaultSource::kBms, 0x0008'0000}},
      {45, {FaultSource::kBms, 0x0010'0000}}, {46, {FaultSource::kBms, 0x0020'0000}},
      {47, {FaultSource::kBms, 0x0040'0000}}, {48, {FaultSource::kBms, 0x0080'0000}},
      {49, {FaultSource::kBms, 0x0100'0000}}, {60, {FaultSource::kObc, 0x0001}},
      {61, {FaultSource::kObc, 0x0002}},      {62, {FaultSource::kObc, 0x0004}},
      {63, {FaultSource::kObc, 0x0008}},      {64, {FaultSource::kObc, 0x0010}},
      {65, {FaultSource::kObc, 0x0020}},      {66, {FaultSource::kObc, 0x0040}},
      {67, {FaultSource::kObc, 0x0080}},      {68, {FaultSource::kObc, 0x0100}},
      {69, {FaultSource::kObc, 0x0200}},      {70, {FaultSource::kObc, 0x0400}},
      {71, {FaultSource::kObc, 0x0800}},      {72, {FaultSource::kObc, 0x1000}},
      {80, {FaultSource::kHmi, 0x0004}},      {81, {FaultSource::kHmi, 0x0008}},
  };
  return codes;
}

TEST(Faults, EverySection4CodeMapsToItsBit) {
  for (const auto& [code, where] : spec_codes()) {
    const FaultDef* d = find_fault(where.first, where.second);
    ASSERT_NE(d, nullptr) << "code " << code;
    EXPECT_EQ(d->code, code);
    EXPECT_EQ(d->source, where.first);
  }
}

TEST(Faults, NoCodeOutsideSection4AndNoCodeTwice) {
  std::set<int> seen;
  for (FaultSource s : kAllSources) {
    for (const FaultDef& d : fault_table(s)) {
      if (d.code < 0) continue;
      EXPECT_TRUE(spec_codes().count(d.code)) << d.code << " " << d.name;
      EXPECT_TRUE(seen.insert(d.code).second) << "code " << d.code << " twice";
    }
  }
  EXPECT_EQ(seen.size(), spec_codes().size());
}

TEST(Faults, DocumentedBitCounts) {
  // MC: 16 low + 8 high; BMS: 16 protection + 9 alarm; OBC 13; IOT 4; lock 7; HMI 4.
  EXPECT_EQ(fault_table(FaultSource::kMc).size(), 24u);
  EXPECT_EQ(fault_table(FaultSource::kBms).size(), 25u);
  EXPECT_EQ(fault_table(FaultSource::kObc).size(), 13u);
  EXPECT_EQ(fault_table(FaultSource::kIot).size(), 4u);
  EXPECT_EQ(fault_table(FaultSource::kLock).size(), 7u);
  EXPECT_EQ(fault_table(FaultSource::kHmi).size(), 4u);
  // Words whose high half the spec fixes at 0x0000 define nothing there.
  for (FaultSource s : {FaultSource::kObc, FaultSource::kIot, FaultSource::kLock}) {
    for (const FaultDef& d : fault_table(s)) EXPECT_EQ(d.mask >> 16, 0u) << d.name;
  }
}

TEST(Faults, EntriesAreWellFormed) {
  for (FaultSource s : kAllSources) {
    std::set<std::string_view> names;
    uint32_t previous = 0;
    for (const FaultDef& d : fault_table(s)) {
      SCOPED_TRACE(std::string(fault_source_name(s)) + "." + std::string(d.name));
      EXPECT_EQ(d.source, s);
      EXPECT_NE(d.mask, 0u);
      EXPECT_EQ(d.mask & (d.mask - 1), 0u) << "not a single bit";
      EXPECT_GT(d.mask, previous) << "not in bit order";
      previous = d.mask;
      EXPECT_TRUE(names.insert(d.name).second) << "name twice";
      EXPECT_FALSE(d.text.empty());
      for (char c : d.name) {
        EXPECT_TRUE((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_');
      }
      EXPECT_EQ(find_fault(s, d.mask), &d);
    }
  }
}

TEST(Faults, SeverityAndUncertaintyFollowTheSpec) {
  auto def = [](FaultSource s, uint32_t mask) {
    const FaultDef* d = find_fault(s, mask);
    EXPECT_NE(d, nullptr) << mask;
    return d ? *d : FaultDef{};
  };
  EXPECT_EQ(def(FaultSource::kMc, 0x0001).severity, Severity::kCritical);       // over-current
  EXPECT_EQ(def(FaultSource::kMc, 0x0001'0000).severity, Severity::kCritical);  // MOS short
  EXPECT_EQ(def(FaultSource::kMc, 0x2000).severity, Severity::kCritical);       // MCU
  EXPECT_EQ(def(FaultSource::kMc, 0x0020).severity, Severity::kWarning);        // speed sensor
  EXPECT_EQ(def(FaultSource::kMc, 0x0400).severity, Severity::kWarning);        // BMS check
  EXPECT_EQ(def(FaultSource::kMc, 0x0080'0000).severity, Severity::kInfo);      // reserved 3
  EXPECT_EQ(def(FaultSource::kBms, 0x0004).severity, Severity::kCritical);      // short circuit
  EXPECT_EQ(def(FaultSource::kBms, 0x0100'0000).severity, Severity::kWarning);  // MOS alarm
  EXPECT_EQ(def(FaultSource::kObc, 0x0800).severity, Severity::kInfo);
  EXPECT_EQ(def(FaultSource::kIot, 0x0004).name, "gps");
  EXPECT_EQ(def(FaultSource::kIot, 0x0001).name, "lte_module");
  EXPECT_EQ(def(FaultSource::kIot, 0x0002).name, "ble_module");
  EXPECT_EQ(def(FaultSource::kIot, 0x0008).name, "unknown");

  // [G] readings are flagged so a configured name table may override them.
  for (uint32_t mask : {0x0080u, 0x0100u, 0x4000u, 0x8000u, 0x0002'0000u, 0x0004'0000u,
                        0x0020'0000u, 0x0040'0000u}) {
    EXPECT_TRUE(def(FaultSource::kMc, mask).uncertain) << std::hex << mask;
  }
  EXPECT_FALSE(def(FaultSource::kMc, 0x0020).uncertain);  // SPS is legible
  EXPECT_TRUE(def(FaultSource::kIot, 0x0001).uncertain);
  EXPECT_FALSE(def(FaultSource::kIot, 0x0004).uncertain);
  EXPECT_TRUE(def(FaultSource::kLock, 0x0040).uncertain);
  EXPECT_TRUE(def(FaultSource::kBms, 0x0800).uncertain);
  EXPECT_FALSE(def(FaultSource::kBms, 0x4000).uncertain);  // AFE is legible
}

TEST(Faults, ForEachActiveFaultVisitsEverySetBitIncludingUndefinedOnes) {
  std::vector<std::pair<uint32_t, const FaultDef*>> seen;
  // MC: over-current, MCU fault, MOS short, and bit 31 which no table defines.
  for_each_active_fault(FaultSource::kMc, 0x8001'2001u,
                        [&](uint32_t mask, const FaultDef* d) { seen.emplace_back(mask, d); });
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_EQ(seen[0].first, 0x0001u);
  ASSERT_NE(seen[0].second, nullptr);
  EXPECT_EQ(seen[0].second->name, "over_current_protect");
  EXPECT_EQ(seen[1].second->code, 27);
  EXPECT_EQ(seen[2].second->name, "mos_short_circuit");
  EXPECT_EQ(seen[3].first, 0x8000'0000u);
  EXPECT_EQ(seen[3].second, nullptr);

  seen.clear();
  for_each_active_fault(FaultSource::kIot, 0,
                        [&](uint32_t m, const FaultDef* d) { seen.emplace_back(m, d); });
  EXPECT_TRUE(seen.empty());

  seen.clear();
  for_each_active_fault(FaultSource::kLock, 0x0000'0180u,
                        [&](uint32_t m, const FaultDef* d) { seen.emplace_back(m, d); });
  ASSERT_EQ(seen.size(), 2u);  // 0x0080 and 0x0100 are reserved for locks
  EXPECT_EQ(seen[0].second, nullptr);
  EXPECT_EQ(seen[1].second, nullptr);
}

TEST(Faults, Names) {
  EXPECT_EQ(fault_source_name(FaultSource::kMc), "mc");
  EXPECT_EQ(fault_source_name(FaultSource::kBms), "bms");
  EXPECT_EQ(fault_source_name(FaultSource::kObc), "obc");
  EXPECT_EQ(fault_source_name(FaultSource::kIot), "iot");
  EXPECT_EQ(fault_source_name(FaultSource::kLock), "lock");
  EXPECT_EQ(fault_source_name(FaultSource::kHmi), "hmi");
  EXPECT_EQ(severity_name(Severity::kInfo), "info");
  EXPECT_EQ(severity_name(Severity::kWarning), "warning");
  EXPECT_EQ(severity_name(Severity::kCritical), "critical");
}

}  // namespace
}  // namespace motinova
