// The signal catalogue (issue 29): derived from the message catalogue, so every decoded field of
// every message has exactly one stable name, and a signal reads the value decode() produced.
#include <gtest/gtest.h>

#include <regex>
#include <set>
#include <string>

#include "motinova/codec.h"
#include "motinova/faults.h"
#include "motinova/signal_catalogue.h"

namespace motinova {
namespace {

const SignalCatalogue& signals() {
  return SignalCatalogue::standard();
}

// The signals a message must have: one per non-reserved field, one per array element, one per
// defined bit of a fault word. Keyword messages carry only their fixed text: none.
std::size_t expected_signals(const MessageDesc& m) {
  if (m.kind == MessageKind::kKeyword) return 0;
  std::size_t n = 0;
  for (const FieldDesc& f : m.fields) {
    if (f.kind == FieldKind::kReserved) continue;
    if (f.kind == FieldKind::kArray) {
      n += f.count;
    } else {
      n += 1;
      if (f.kind == FieldKind::kFaultWord) n += fault_table(m.fault_source).size();
    }
  }
  return n;
}

TEST(SignalCatalogue, EveryDecodedFieldOfEveryMessageHasAnEntry) {
  std::size_t total = 0;
  for (const MessageDesc& m : Catalogue::standard().messages()) {
    const auto of = signals().of_message(&m);
    ASSERT_EQ(of.size(), expected_signals(m)) << m.name << " on 0x" << std::hex << m.can_id;
    for (const FieldDesc& f : m.fields) {
      if (f.kind == FieldKind::kReserved || m.kind == MessageKind::kKeyword) continue;
      bool found = false;
      for (const Signal& s : of) found = found || s.field == &f;
      EXPECT_TRUE(found) << m.name << "." << f.name << " has no signal";
    }
    for (const Signal& s : of) {
      EXPECT_EQ(s.message, &m);
      EXPECT_EQ(s.unit, s.field->unit) << s.name;
      EXPECT_EQ(signals().find(s.name), &s) << s.name;
    }
    total += of.size();
  }
  EXPECT_EQ(total, signals().signals().size());
}

TEST(SignalCatalogue, NamesAreUniqueDottedAndPrefixedByTheSourceNode) {
  const std::regex pattern(R"([a-z0-9]+\.[a-z0-9_]+\.[a-z0-9_]+(\[[0-9]+\])?)");
  std::set<std::string> seen;
  for (const Signal& s : signals().signals()) {
    EXPECT_TRUE(std::regex_match(s.name, pattern)) << s.name;
    EXPECT_TRUE(seen.insert(s.name).second) << "duplicate " << s.name;
    EXPECT_TRUE(s.name.starts_with(std::string(node_name(s.message->source())) + ".")) << s.name;
    EXPECT_EQ(&signals().signals()[s.id], &s);
  }
}

TEST(SignalCatalogue, KnownNamesUnitsAndTypes) {
  const Signal* cell = signals().find("bms.cells.cells_mv[7]");
  ASSERT_NE(cell, nullptr);
  EXPECT_EQ(cell->unit, "mV");
  EXPECT_EQ(cell->type, SignalType::kNumber);
  EXPECT_EQ(cell->element, 7);
  EXPECT_EQ(cell->message->can_id, 0x720);
  EXPECT_EQ(signals().find("bms.cells.cells_mv[16]"), nullptr);

  const Signal* motor = signals().find("mc.status.motor_temp_c");
  ASSERT_NE(motor, nullptr);
  EXPECT_EQ(motor->unit, "°C");
  const Signal* alarm = signals().find("bms.faults.charge_over_voltage_alarm");
  ASSERT_NE(alarm, nullptr);
  EXPECT_EQ(alarm->type, SignalType::kBool);
  EXPECT_EQ(alarm->fault_mask, 0x00010000u);
  EXPECT_EQ(signals().find("lock4.status.motor_rpm")->message->can_id, 0x7A0);
  EXPECT_EQ(signals().find("mc.device_info.fw")->type, SignalType::kText);
  EXPECT_EQ(signals().find("bms.status.charging")->type, SignalType::kBool);
  // The V3.0 layout of the MC settings (0x714) does not take the V4.6.2 name (0x713).
  EXPECT_EQ(signals().find("mc.settings.wheel_size_cm")->message->can_id, 0x713);
  EXPECT_EQ(signals().find("mc.settings_714.wheel_size_cm")->message->can_id, 0x714);
}

TEST(SignalCatalogue, ReadsWhatDecodeProduced) {
  const DecodeOptions options;
  const Catalogue& cat = Catalogue::standard();
  const AppFrame cells = MessageWriter(*cat.find("bms_cells", 0x720), options)
                             .element("cells_mv", 7, 3456)
                             .element("cells_mv", 0, 3001)
                             .frame();
  DecodedMessage m;
  decode(cells, cat, options, m);
  auto v = SignalCatalogue::read(*signals().find("bms.cells.cells_mv[7]"), m);
  ASSERT_TRUE(v && v->valid);
  EXPECT_EQ(v->number, 3456.0);
  EXPECT_EQ(SignalCatalogue::read(*signals().find("bms.cells.cells_mv[0]"), m)->number, 3001.0);

  const AppFrame faults =
      MessageWriter(*cat.find("bms_faults", 0x720), options).raw("raw", 0x00010004).frame();
  decode(faults, cat, options, m);
  EXPECT_EQ(
      SignalCatalogue::read(*signals().find("bms.faults.charge_over_voltage_alarm"), m)->number,
      1.0);
  EXPECT_EQ(SignalCatalogue::read(*signals().find("bms.faults.short_circuit_protect"), m)->number,
            1.0);
  EXPECT_EQ(SignalCatalogue::read(*signals().find("bms.faults.over_voltage_protect"), m)->number,
            0.0);

  const AppFrame status =
      MessageWriter(*cat.find("mc_status", 0x710), options).value("motor_temp_c", 61).frame();
  decode(status, cat, options, m);
  EXPECT_EQ(SignalCatalogue::read(*signals().find("mc.status.motor_temp_c"), m)->number, 61.0);
  // A signal of another message is not in this one.
  EXPECT_FALSE(SignalCatalogue::read(*signals().find("bms.status.temp_c"), m).has_value());
}

}  // namespace
}  // namespace motinova
