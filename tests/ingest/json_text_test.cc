// The JSON text of the jsonb columns written directly (backend/ingest/json_text.h, issue 25):
// byte for byte what nlohmann::json's dump wrote before, for every string a bike can send
// (quotes, backslashes, every control character, multi-byte UTF-8, invalid UTF-8 replaced by
// U+FFFD), so jsonb receives the same documents.
#include "backend/ingest/json_text.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <random>
#include <string>
#include <vector>

namespace {

using fleetgw::ingest::append_json_string;
using fleetgw::ingest::JsonWriter;

std::string reference(const std::string& s) {
  return nlohmann::json(s).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string written(const std::string& s) {
  std::string out;
  append_json_string(out, s);
  return out;
}

TEST(JsonText, StringsAreWhatNlohmannWrote) {
  std::vector<std::string> cases = {"",
                                    "plain",
                                    "say \"hi\"",
                                    "back\\slash",
                                    "tab\tnew\nline\rret\bbs\fff",
                                    "slash / and DEL \x7f",
                                    "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x9a\xb2",
                                    "bad \xff byte",
                                    "cut \xe2\x82",
                                    "overlong \xc0\xaf",
                                    "surrogate \xed\xa0\x80",
                                    "above \xf4\x90\x80\x80"};
  for (int c = 1; c < 0x20; ++c) cases.push_back(std::string("ctl ") + static_cast<char>(c) + ".");
  for (const std::string& s : cases) EXPECT_EQ(written(s), reference(s)) << s;
}

TEST(JsonText, RandomBytesAreWhatNlohmannWrote) {
  // Bytes drawn mostly from the troublesome ranges: controls, quotes, UTF-8 lead and
  // continuation bytes (valid and invalid sequences alike).
  std::mt19937 rng(25);
  const std::string alphabet = std::string("a\"\\\t\n\x01\x1f\x7f") + "\xc3\xa9\xe2\x82\xac\xf0\x9f" +
                               "\x80\xbf\xc0\xed\xa0\xf4\x90\xff";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  std::uniform_int_distribution<int> len(0, 12);
  for (int i = 0; i < 20000; ++i) {
    std::string s;
    for (int n = len(rng); n > 0; --n) s += alphabet[pick(rng)];
    ASSERT_EQ(written(s), reference(s)) << i;
  }
}

TEST(JsonText, WriterMakesTheDocumentNlohmannDumped) {
  std::string out;
  JsonWriter j(out);
  j.begin_array();
  for (int i = 0; i < 2; ++i) {
    j.begin_object();
    j.key("code");
    i == 0 ? j.number(12) : j.null();
    j.key("name");
    j.string(i == 0 ? "over_temp" : "say \"hi\"");
    j.key("tags");
    j.begin_array();
    j.end_array();
    j.end_object();
  }
  j.end_array();
  nlohmann::json doc = nlohmann::json::array();
  doc.push_back({{"code", 12}, {"name", "over_temp"}, {"tags", nlohmann::json::array()}});
  doc.push_back({{"code", nullptr}, {"name", "say \"hi\""}, {"tags", nlohmann::json::array()}});
  EXPECT_EQ(out, doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  std::string empty;
  JsonWriter e(empty);
  e.begin_array();
  e.end_array();
  EXPECT_EQ(empty, "[]");
}

}  // namespace
