// Round trip over EVERY catalogue message: random raw field values -> MessageWriter -> encode ->
// segment -> interleave with messages on other IDs -> Reassembler -> decode -> the same raws.
// Run under several option sets so that every uncertain-reading knob that changes the wire
// (byte order, CRC order, fault layouts, current sign, voltage/current position) is exercised.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "motinova/codec.h"
#include "motinova/reassembler.h"
#include "motinova/segmenter.h"
#include "test_util.h"

namespace motinova {
namespace {

// What the writer was given, per field, to compare after decoding.
struct Expected {
  const MessageDesc* desc = nullptr;
  std::map<std::string_view, int64_t> raws;
  std::map<std::string_view, std::string> texts;
  std::map<std::string_view, std::vector<uint64_t>> elements;
};

bool reads_signed(const FieldDesc& f, const DecodeOptions& o) {
  return f.kind == FieldKind::kSigned || (f.quirk == Quirk::kMcCurrent && o.mc_current_signed);
}

// Builds one message with random content; records the expectation.
AppFrame random_message(const MessageDesc& desc, const DecodeOptions& options, std::mt19937& rng,
                        Expected& expected) {
  expected = Expected{};
  expected.desc = &desc;
  MessageWriter writer(desc, options);
  auto uniform = [&](int64_t lo, int64_t hi) {
    return std::uniform_int_distribution<int64_t>(lo, hi)(rng);
  };

  for (const FieldDesc& f : desc.fields) {
    const int64_t bits = 8 * f.size;
    switch (f.kind) {
      case FieldKind::kReserved:
        break;
      case FieldKind::kAscii: {
        if (desc.kind == MessageKind::kKeyword) {
          expected.texts[f.name] = std::string(desc.keyword);
          break;
        }
        std::string text(static_cast<std::size_t>(uniform(0, f.size)), ' ');
        for (char& c : text) c = static_cast<char>(uniform(0x21, 0x7E));  // no trailing space
        if (text.size() > 2) text[1] = ' ';  // inner spaces survive trimming
        writer.text(f.name, text);
        expected.texts[f.name] = text;
        break;
      }
      case FieldKind::kBytes:
      case FieldKind::kArray: {
        const std::size_t count = f.kind == FieldKind::kArray ? f.count : f.size;
        const int64_t max = f.kind == FieldKind::kArray ? (int64_t{1} << bits) - 1 : 0xFF;
        auto& elements = expected.elements[f.name];
        for (std::size_t i = 0; i < count; ++i) {
          elements.push_back(static_cast<uint64_t>(uniform(0, max)));
          writer.element(f.name, i, elements.back());
        }
        break;
      }
      case FieldKind::kFaultWord:
        expected.raws[f.name] = uniform(0, 0xFFFFFFFF);
        writer.raw(f.name, expected.raws[f.name]);
        break;
      case FieldKind::kBool:
        if (f.bool_mask != 0) break;  // an overlay: its byte is written through the flags field
        expected.raws[f.name] = uniform(0, 1) ? f.true_raw : f.false_raw;
        writer.raw(f.name, expected.raws[f.name]);
        break;
      default: {
        const int64_t lo = reads_signed(f, options) ? -(int64_t{1} << (bits - 1)) : 0;
        const int64_t hi =
            reads_signed(f, options) ? (int64_t{1} << (bits - 1)) - 1 : (int64_t{1} << bits) - 1;
        expected.raws[f.name] = uniform(lo, hi);
        writer.raw(f.name, expected.raws[f.name]);
        break;
      }
    }
  }
  // Masked booleans read the same wire integer as the flags field they sit on.
  for (const FieldDesc& f : desc.fields) {
    if (f.kind != FieldKind::kBool || f.bool_mask == 0) continue;
    for (const FieldDesc& g : desc.fields) {
      if (g.kind == FieldKind::kFlags && g.offset == f.offset) {
        expected.raws[f.name] = expected.raws[g.name];
      }
    }
  }
  return writer.frame();
}

void check(const AppFrame& frame, const Expected& e, const DecodeOptions& options) {
  SCOPED_TRACE(std::string(e.desc->name) + " on " + std::to_string(e.desc->can_id));
  DecodedMessage m;
  decode(frame, Catalogue::standard(), options, m);
  ASSERT_EQ(m.status, DecodeStatus::kOk);
  EXPECT_EQ(m.desc, e.desc);
  EXPECT_TRUE(m.mode_matches);
  for (const auto& [name, raw] : e.raws) {
    ASSERT_TRUE(m.raw(name).has_value()) << name;
    EXPECT_EQ(*m.raw(name), raw) << name;
  }
  for (const auto& [name, text] : e.texts) EXPECT_EQ(m.text(name), text) << name;
  for (const auto& [name, elements] : e.elements) {
    for (std::size_t i = 0; i < elements.size(); ++i) {
      ASSERT_TRUE(m.element(name, i).has_value()) << name << "[" << i << "]";
      EXPECT_EQ(*m.element(name, i), elements[i]) << name << "[" << i << "]";
    }
  }
  // Every exposed field was checked.
  EXPECT_EQ(m.values().size(), e.raws.size() + e.texts.size() + e.elements.size());
}

struct OptionSet {
  const char* name;
  DecodeOptions options;
};

std::vector<OptionSet> option_sets() {
  std::vector<OptionSet> sets;
  sets.push_back({"defaults", DecodeOptions{}});
  DecodeOptions le;
  le.data_order = ByteOrder::kLittle;
  le.crc_order = CrcOrder::kLittle;
  le.mc_fault_layout = FaultWordLayout::kSwappedGroups;
  le.bms_fault_layout = FaultWordLayout::kTwoWordsLowFirst;
  le.other_fault_layout = FaultWordLayout::kSwappedGroups;
  le.bms_current_charge_positive = false;
  le.mc_current_signed = true;
  le.mc_voltage_current_order = McVoltageCurrentOrder::kCurrentFirst;
  sets.push_back({"little_endian_alternatives", le});
  DecodeOptions two_words;
  two_words.mc_fault_layout = FaultWordLayout::kTwoWordsLowFirst;
  two_words.other_fault_layout = FaultWordLayout::kTwoWordsLowFirst;
  sets.push_back({"two_word_faults", two_words});
  return sets;
}

class RoundTrip : public ::testing::TestWithParam<OptionSet> {};

TEST_P(RoundTrip, EveryCatalogueMessageSurvivesTheBus) {
  const DecodeOptions& options = GetParam().options;
  const auto messages = Catalogue::standard().messages();
  std::mt19937 rng(20240611);

  // Spread the messages over "lanes" so that each batch holds at most one message per CAN ID
  // (a sender never interleaves two messages on one ID) but several IDs at once.
  std::map<uint16_t, std::vector<const MessageDesc*>> by_id;
  for (const MessageDesc& d : messages) by_id[d.can_id].push_back(&d);

  auto reassembler = std::make_unique<Reassembler>(
      ReassemblerOptions{.gap_timeout = Micros{100'000}, .crc_order = options.crc_order});
  test::RecordingSink sink;
  Micros now{1'000'000};
  std::size_t checked = 0;

  for (int repeat = 0; repeat < 3; ++repeat) {
    for (std::size_t round = 0;; ++round) {
      std::vector<Expected> batch;
      std::vector<std::vector<CanFrame>> segments;
      for (const auto& [id, list] : by_id) {
        if (round >= list.size()) continue;
        batch.emplace_back();
        const AppFrame frame = random_message(*list[round], options, rng, batch.back());
        segments.push_back(segment(frame, options.crc_order));
      }
      if (batch.empty()) break;
      // Round-robin interleaving of the segments of all IDs in the batch.
      sink.frames.clear();
      for (std::size_t i = 0;; ++i) {
        bool any = false;
        for (const auto& s : segments) {
          if (i >= s.size()) continue;
          any = true;
          now += Micros{500};
          reassembler->push(s[i], now, sink);
        }
        if (!any) break;
      }
      ASSERT_TRUE(sink.errors.empty()) << reassembly_error_name(sink.errors.front().kind) << " on "
                                       << sink.errors.front().can_id;
      ASSERT_EQ(sink.frames.size(), batch.size());
      for (const AppFrame& f : sink.frames) {
        const auto it = std::find_if(batch.begin(), batch.end(),
                                     [&](const Expected& e) { return e.desc->can_id == f.can_id; });
        ASSERT_NE(it, batch.end());
        check(f, *it, options);
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 3 * messages.size());
  EXPECT_EQ(reassembler->stats().frames_ok, checked);
}

INSTANTIATE_TEST_SUITE_P(Options, RoundTrip, ::testing::ValuesIn(option_sets()),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace motinova
