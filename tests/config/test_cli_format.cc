// The pieces behind `--since` and `--format table|json|csv` (gateway/tools/common/time_arg.h,
// table_format.h): every accepted form of a time, the refused ones, RFC 4180 CSV read back by
// a strict reader, and hostile strings that must never break a table row.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "gateway/tools/common/table_format.h"
#include "gateway/tools/common/time_arg.h"

namespace fleetgw::tools::cli_format_test {
namespace {

using nlohmann::json;

constexpr std::int64_t kS = 1'000'000;
// 2026-11-27T10:00:00Z: 20,784 days after the epoch.
constexpr std::int64_t kTenOClock = (20'784LL * 86'400 + 10 * 3600) * kS;

TEST(ParseSince, MicrosecondsSinceTheEpochAsBefore) {
  EXPECT_EQ(parse_since("0", 0), 0);
  EXPECT_EQ(parse_since("1763700000000000", 0), 1763700000000000);
  EXPECT_FALSE(parse_since("99999999999999999999", 0));  // above int64
}

TEST(ParseSince, RelativeTimesCountBackFromNow) {
  const std::int64_t now = kTenOClock;
  EXPECT_EQ(parse_since("90s", now), now - 90 * kS);
  EXPECT_EQ(parse_since("15m", now), now - 15 * 60 * kS);
  EXPECT_EQ(parse_since("2h", now), now - 2 * 3600 * kS);
  EXPECT_EQ(parse_since("3d", now), now - 3 * 86400 * kS);
  EXPECT_EQ(parse_since("0s", now), now);
  for (const char* bad :
       {"2h30m", "h", "-5m", "5 m", "5M", "1.5h", "2w", "5ms", "999999999999999d"}) {
    EXPECT_FALSE(parse_since(bad, now)) << bad;
  }
}

TEST(ParseSince, Iso8601DateTimesAndDates) {
  EXPECT_EQ(parse_since("2026-11-27T10:00:00Z", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27t10:00:00z", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27 10:00:00Z", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27T10:00Z", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27T10:00:00", 0), kTenOClock);  // no zone: UTC
  EXPECT_EQ(parse_since("2026-11-27T12:00:00+02:00", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27T05:30:00-0430", 0), kTenOClock);
  EXPECT_EQ(parse_since("2026-11-27T10:00:00.25Z", 0), kTenOClock + 250'000);
  EXPECT_EQ(parse_since("2026-11-27T10:00:00.000001Z", 0), kTenOClock + 1);
  EXPECT_EQ(parse_since("2026-11-27", 0), kTenOClock - 10 * 3600 * kS);
  EXPECT_EQ(parse_since("1970-01-01", 0), 0);
  EXPECT_EQ(parse_since("2028-02-29", 0).has_value(), true);  // leap year
}

TEST(ParseSince, RefusesWhatIsNotATime) {
  for (const char* bad : {"",
                          "yesterday",
                          "now",
                          "2026-02-30",
                          "2026-02-29",
                          "2026-13-01",
                          "2026-00-10",
                          "2026-11-27T24:00:00Z",
                          "2026-11-27T10:60:00Z",
                          "2026-11-27T10:00:60Z",
                          "2026-11-27T",
                          "2026-11-27T10",
                          "2026-11-27T10:00:00X",
                          "2026-11-27T10:00:00Z ",
                          " 2026-11-27",
                          "2026-11-27T10:00:00.Z",
                          "2026-11-27T10:00:00.1234567Z",
                          "26-11-27",
                          "2026/11/27",
                          "2026-11-27T10:00:00+2",
                          "-1",
                          "1e6"}) {
    EXPECT_FALSE(parse_since(bad, kTenOClock)) << '"' << bad << '"';
  }
}

TEST(IsoUtc, FormatsWholeSecondsInUtc) {
  EXPECT_EQ(iso_utc(0), "1970-01-01T00:00:00Z");
  EXPECT_EQ(iso_utc(kTenOClock), "2026-11-27T10:00:00Z");
  EXPECT_EQ(iso_utc(kTenOClock + 999'999), "2026-11-27T10:00:00Z");
  EXPECT_EQ(iso_utc(-1), "1969-12-31T23:59:59Z");
  EXPECT_EQ(parse_since(iso_utc(kTenOClock + 3723 * kS), 0), kTenOClock + 3723 * kS);
}

// A strict RFC 4180 reader: records end in CRLF; quoted fields may hold anything.
std::vector<std::vector<std::string>> read_csv(const std::string& text) {
  std::vector<std::vector<std::string>> records;
  std::vector<std::string> record;
  std::string field;
  std::size_t i = 0;
  bool quoted = false;
  while (i < text.size()) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        i += 2;
      } else if (c == '"') {
        quoted = false;
        ++i;
      } else {
        field += c;
        ++i;
      }
    } else if (c == '"' && field.empty()) {
      quoted = true;
      ++i;
    } else if (c == ',') {
      record.push_back(std::move(field));
      field.clear();
      ++i;
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      record.push_back(std::move(field));
      field.clear();
      records.push_back(std::move(record));
      record.clear();
      i += 2;
    } else {
      EXPECT_NE(c, '"') << "bare quote inside an unquoted field";
      EXPECT_NE(c, '\n') << "bare LF: not RFC 4180";
      EXPECT_NE(c, '\r') << "bare CR: not RFC 4180";
      field += c;
      ++i;
    }
  }
  EXPECT_FALSE(quoted) << "unterminated quoted field";
  EXPECT_TRUE(field.empty() && record.empty()) << "last record without CRLF";
  return records;
}

const std::string kHostile = "line1\nline2\r\n\"quoted\", comma\x1b[31m\ttab\\";

TEST(Csv, FieldsAreQuotedOnlyWhenNeeded) {
  EXPECT_EQ(csv_field("plain text"), "plain text");
  EXPECT_EQ(csv_field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csv_field("cr\r"), "\"cr\r\"");
  EXPECT_EQ(csv_field("esc\x1b"), "\"esc\x1b\"");
  EXPECT_EQ(csv_field(""), "");
  EXPECT_EQ(csv_field("bad\xff"), "bad\xef\xbf\xbd");  // invalid UTF-8 -> U+FFFD
}

TEST(Csv, HostileStringsReadBackExactly) {
  Table t;
  t.columns = {{"name", "NAME"}, {"n", "N"}, {"x", "X", 2}, {"missing", "MISSING"}};
  t.rows = {{kHostile, 1, 2.345, nullptr}, {"ok", -2, 1.0, true}};
  std::ostringstream out;
  write_csv(t, out);
  const auto records = read_csv(out.str());
  ASSERT_EQ(records.size(), 3u) << out.str();
  EXPECT_EQ(records[0], (std::vector<std::string>{"name", "n", "x", "missing"}));
  EXPECT_EQ(records[1], (std::vector<std::string>{kHostile, "1", "2.35", ""}));
  EXPECT_EQ(records[2], (std::vector<std::string>{"ok", "-2", "1.00", "true"}));
}

// OWASP's CSV injection rule: a text cell that starts with =, +, -, @, TAB or CR would be run as
// a formula by a spreadsheet (`=cmd|'/Ccalc'!A0` from a BMS serial on the bus). It is written
// with a leading ' and quoted; a text cell that starts with ' gets one more, so removing one
// leading ' from every text cell that starts with one gives the stored text back. Numbers stay
// numbers: -3.5 A is not text.
TEST(Csv, FormulaCellsFromTheBusAreNeutralised) {
  EXPECT_EQ(csv_field("=cmd|'/Ccalc'!A0"), "\"'=cmd|'/Ccalc'!A0\"");
  EXPECT_EQ(csv_field("+1+1"), "\"'+1+1\"");
  EXPECT_EQ(csv_field("-2+3"), "\"'-2+3\"");
  EXPECT_EQ(csv_field("@SUM(A1)"), "\"'@SUM(A1)\"");
  EXPECT_EQ(csv_field("\t=1"), "\"'\t=1\"");
  EXPECT_EQ(csv_field("\r=1"), "\"'\r=1\"");
  EXPECT_EQ(csv_field("'quoted"), "\"''quoted\"");
  EXPECT_EQ(csv_field("a=b"), "a=b");  // only the first character counts
  EXPECT_EQ(csv_field("BMS-0042"), "BMS-0042");

  Table t;
  t.columns = {{"serial", "SERIAL"}, {"current_a", "A", -1}, {"n", "N"}, {"doc", "DOC"}};
  t.rows = {{"=HYPERLINK(\"http://x\",\"y\")", -3.5, -2, json::array({-1})},
            {"-3.5", 0.0, 0, json("@x")}};
  std::ostringstream out;
  write_csv(t, out);
  const auto records = read_csv(out.str());
  ASSERT_EQ(records.size(), 3u) << out.str();
  EXPECT_EQ(records[1],
            (std::vector<std::string>{"'=HYPERLINK(\"http://x\",\"y\")", "-3.5", "-2", "[-1]"}));
  // A string that looks like a negative number is still text from the store: neutralised.
  EXPECT_EQ(records[2], (std::vector<std::string>{"'-3.5", "0.0", "0", "'@x"}));
  // Every cell a spreadsheet would evaluate begins with the quote.
  for (const auto& record : records) {
    for (const auto& cell : record) {
      EXPECT_TRUE(cell.empty() || std::string_view("=+@\t\r").find(cell[0]) == std::string::npos)
          << cell;
    }
  }
}

std::size_t code_points(const std::string& s) {
  return static_cast<std::size_t>(std::count_if(
      s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; }));
}

TEST(TableOutput, ControlCharactersNeverBreakARow) {
  Table t;
  t.columns = {{"name", "NAME"}, {"km", "KM", 2}};
  t.rows = {{kHostile, 8.1}, {"short", nullptr}, {"bad\xff utf8 \xe2\x80\xa8 sep", 12.345}};
  std::ostringstream out;
  write_table(t, out);
  const std::string text = out.str();
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 4u) << text;  // header + 3 rows, whatever the strings hold
  for (const auto& l : lines) {
    for (const char c : l) {
      EXPECT_FALSE(static_cast<unsigned char>(c) < 0x20 || c == 0x7f) << "control in: " << l;
    }
  }
  EXPECT_NE(lines[1].find("line1\\nline2\\r\\n\"quoted\", comma\\x1b[31m\\ttab\\\\"),
            std::string::npos)
      << lines[1];
  EXPECT_EQ(lines[2].substr(0, 5), "short");
  EXPECT_EQ(lines[2].back(), '-');  // null
  EXPECT_NE(lines[3].find("\xef\xbf\xbd"), std::string::npos);
  EXPECT_EQ(lines[3].find("\xe2\x80\xa8"), std::string::npos);
  // Numbers right-aligned with the column's decimals; every row as wide as the header's start.
  EXPECT_EQ(lines[1].substr(lines[1].size() - 4), "8.10");
  EXPECT_EQ(lines[3].substr(lines[3].size() - 5), "12.35");
  for (const auto& l : lines) EXPECT_EQ(code_points(l), code_points(lines[0])) << l;
}

TEST(TableOutput, AlignsColumnsByCodePoints) {
  Table t;
  t.columns = {{"a", "A"}, {"b", "B"}};
  t.rows = {{"\xc3\xa9t\xc3\xa9", "x"}, {"long value", "y"}};  // "été": 3 code points, 5 bytes
  std::ostringstream out;
  write_table(t, out);
  EXPECT_EQ(out.str(), "A" + std::string(11, ' ') + "B\n\xc3\xa9t\xc3\xa9" + std::string(9, ' ') +
                           "x\nlong value  y\n");
}

TEST(TableOutput, NoRowsSaysSo) {
  Table t;
  t.columns = {{"a", "A"}};
  std::ostringstream table, json_out, csv;
  write_table(t, table);
  write_json(t, json_out);
  write_csv(t, csv);
  EXPECT_EQ(table.str(), "(no rows)\n");
  EXPECT_EQ(json_out.str(), "[]\n");
  EXPECT_EQ(csv.str(), "a\r\n");
}

TEST(JsonOutput, TypedValuesOneRowPerLineInvalidUtf8Replaced) {
  Table t;
  t.columns = {{"name", "NAME"}, {"km", "KM", 2}, {"n", "N"}};
  t.rows = {{"bad\xff", 8.123456, 3}, {kHostile, nullptr, -1}};
  std::ostringstream out;
  ASSERT_NO_THROW(write_json(t, out));
  const auto doc = json::parse(out.str());
  ASSERT_EQ(doc.size(), 2u);
  EXPECT_EQ(doc[0]["name"], "bad\xef\xbf\xbd");
  EXPECT_DOUBLE_EQ(doc[0]["km"].get<double>(), 8.12);
  EXPECT_EQ(doc[0]["n"], 3);
  EXPECT_EQ(doc[1]["name"], kHostile);
  EXPECT_TRUE(doc[1]["km"].is_null());
  const std::string text = out.str();
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 4);  // [, 2 rows, ]
}

TEST(Flatten, NestedDocumentsBecomeDottedKeys) {
  const auto doc = json::parse(
      R"({"tables":{"rides":3},"attention":["disk full"],"ok":true,"empty":{},"none":null})");
  const Table t = flatten(doc);
  std::ostringstream out;
  write_csv(t, out);
  EXPECT_EQ(out.str(),
            "key,value\r\nattention.0,disk full\r\nnone,\r\nok,true\r\ntables.rides,3\r\n");
  EXPECT_EQ(parse_output_format("csv"), OutputFormat::kCsv);
  EXPECT_FALSE(parse_output_format("CSV"));
}

}  // namespace
}  // namespace fleetgw::tools::cli_format_test
