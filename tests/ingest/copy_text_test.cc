// The COPY text the ingest builds straight from decoded messages (backend/ingest/copy_text.h,
// issue 25): every byte survives the COPY escaping and the text[] element made from it (the
// ON CONFLICT path of a redelivery, the latest-value upserts), NULL stays NULL and the string
// "\N" stays a string.
#include "backend/ingest/copy_text.h"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "backend/ingest/envelope_rows.h"
#include "fleetgw/v1/envelope.pb.h"

namespace {

using fleetgw::ingest::append_array_element;
using fleetgw::ingest::append_copy_text;
using fleetgw::ingest::copy_value;
using fleetgw::ingest::next_row;
using fleetgw::ingest::split_row;

const std::vector<std::string> kHostile = {
    "",
    "plain",
    "tab\there",
    "new\nline and \r return",
    "back\\slash \\N \\t",
    "\\N",
    "\"quoted\" {braces}, comma",
    std::string("not utf-8 \xff\xfe\x80", 14),
    std::string("embedded \0 zero", 15),
    "\\",
};

TEST(CopyText, EveryByteSurvivesTheCopyEscapingAndSeparatorsStaySeparators) {
  std::string rows;
  for (const std::string& v : kHostile) {
    append_copy_text(rows, v);
    rows += '\t';
    rows += "\\N";  // a NULL after each value
    rows += '\n';
  }
  std::string_view rest = rows;
  std::vector<std::string_view> fields;
  for (const std::string& v : kHostile) {
    const std::string_view row = next_row(rest);
    split_row(row, fields);
    ASSERT_EQ(fields.size(), 2u) << "a value's tab or newline leaked as a separator: " << row;
    EXPECT_EQ(copy_value(fields[0]), std::optional<std::string>(v));
    EXPECT_EQ(copy_value(fields[1]), std::nullopt);
  }
  EXPECT_TRUE(rest.empty());
}

// PostgreSQL's array input: an element is NULL, or double-quoted with `"` and `\` escaped.
// Decoding the literal the way the server does gives back every value.
std::vector<std::optional<std::string>> parse_array(std::string_view a) {
  std::vector<std::optional<std::string>> out;
  EXPECT_EQ(a.front(), '{');
  std::size_t i = 1;
  while (i < a.size() && a[i] != '}') {
    if (a.substr(i, 4) == "NULL") {
      out.emplace_back(std::nullopt);
      i += 4;
    } else {
      EXPECT_EQ(a[i], '"');
      std::string v;
      for (++i; a[i] != '"'; ++i) {
        if (a[i] == '\\') ++i;
        v += a[i];
      }
      out.emplace_back(v);
      ++i;
    }
    if (a[i] == ',') ++i;
  }
  return out;
}

TEST(CopyText, ArrayElementsFromCopyTextKeepEveryByteAndNull) {
  std::string array = "{";
  std::vector<std::optional<std::string>> expected;
  for (const std::string& v : kHostile) {
    std::string escaped;
    append_copy_text(escaped, v);
    append_array_element(array, escaped);
    expected.emplace_back(v);
    append_array_element(array, "\\N");
    expected.emplace_back(std::nullopt);
  }
  array += '}';
  EXPECT_EQ(parse_array(array), expected);
}

// A decoded message's rows: an absent optional field is NULL (\N), never 0 or "".
TEST(CopyText, DecodedTelemetryRowsHaveNullForAbsentFields) {
  fleetgw::v1::Envelope e;
  e.set_vehicle_id("bike-1");
  e.set_store_id("store\ta");
  auto* s = e.mutable_telemetry()->add_samples();
  s->set_sequence(7);
  s->set_speed_dkmh(0);  // present, zero
  auto r = fleetgw::ingest::decode_message("fleet/v1", "fleet/v1/bike-1/telemetry",
                                           e.SerializeAsString());
  const auto& d = std::get<fleetgw::ingest::Decoded>(r);
  ASSERT_EQ(d.rows.at(0).rows(), 1u);
  const auto v = d.rows[0].values();
  ASSERT_EQ(v.size(), 27u);
  EXPECT_EQ(v[1], std::optional<std::string>("store\ta"));
  EXPECT_EQ(v[5], std::optional<std::string>("0"));  // speed_dkmh
  EXPECT_EQ(v[6], std::nullopt);                      // motor_rpm absent
  EXPECT_EQ(v[23], std::nullopt);                     // no position
}

}  // namespace
