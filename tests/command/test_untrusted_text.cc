// common/untrusted_text: received strings made safe for logs, stored reasons and protobuf.
#include <gtest/gtest.h>

#include <string>

#include "gateway/common/untrusted_text.h"

namespace fleetgw::common {
namespace {

const std::string kE = "\xC3\xA9";  // é, two bytes

TEST(UntrustedText, TruncationNeverCutsACodePoint) {
  const std::string key = std::string(63, 'a') + kE;  // 65 bytes: a cut at 64 lands inside é
  const std::string cut = truncate_utf8(key, 64);
  EXPECT_EQ(cut, std::string(63, 'a'));
  EXPECT_TRUE(is_valid_utf8(cut));
  EXPECT_EQ(truncate_utf8(key, 65), key);
  // Every limit on a string of 1..4-byte code points yields valid UTF-8 no longer than asked.
  const std::string mixed = "a" + kE + "\xE2\x82\xAC" + "\xF0\x9F\x9A\xB2" + "z";
  for (std::size_t n = 0; n <= mixed.size() + 1; ++n) {
    const std::string t = truncate_utf8(mixed, n);
    EXPECT_LE(t.size(), n);
    EXPECT_TRUE(is_valid_utf8(t)) << n;
    EXPECT_EQ(mixed.compare(0, t.size(), t), 0) << n;
  }
}

TEST(UntrustedText, InvalidBytesBecomeReplacementCharacters) {
  EXPECT_FALSE(is_valid_utf8("\xC3"));              // truncated
  EXPECT_FALSE(is_valid_utf8("\xC0\xAF"));          // overlong '/'
  EXPECT_FALSE(is_valid_utf8("\xED\xA0\x80"));      // surrogate
  EXPECT_FALSE(is_valid_utf8("\xF4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_TRUE(is_valid_utf8("\xF4\x8F\xBF\xBF"));
  EXPECT_EQ(valid_utf8("ok\xFFok"), "ok\xEF\xBF\xBDok");
  EXPECT_TRUE(is_valid_utf8(escape_controls("\xC3(\x80")));
  EXPECT_TRUE(is_valid_utf8(untrusted_excerpt(std::string(100, '\xFF'), 64)));
}

TEST(UntrustedText, ControlCharactersAreEscapedToOneLine) {
  EXPECT_EQ(escape_controls("a\nb\r\tc\x1B[31m\x7F"), "a\\nb\\r\\tc\\x1b[31m\\x7f");
  EXPECT_EQ(escape_controls("back\\slash"), "back\\\\slash");                  // unambiguous
  EXPECT_EQ(escape_controls("\xC2\x85|\xE2\x80\xA8"), "\\u{0085}|\\u{2028}");  // NEL, LS
  EXPECT_EQ(escape_controls(std::string("nul\0x", 5)), "nul\\x00x");
  EXPECT_EQ(escape_controls("caf" + kE), "caf" + kE);  // printable text untouched
}

TEST(UntrustedText, ExcerptIsBoundedAndMarksTheCut) {
  EXPECT_EQ(untrusted_excerpt("short", 64), "short");
  const std::string forged = "x\n2026-11-23 [info] command ok";
  const std::string e = untrusted_excerpt(forged, 64);
  EXPECT_EQ(e.find('\n'), std::string::npos);
  EXPECT_EQ(e, "x\\n2026-11-23 [info] command ok");
  const std::string long_text(200, 'a');
  const std::string cut = untrusted_excerpt(long_text, 64);
  EXPECT_EQ(cut.size(), 64u);
  EXPECT_EQ(cut.substr(61), "...");
  // Never cut inside an escape or a code point.
  const std::string many_newlines(100, '\n');
  const std::string n = untrusted_excerpt(many_newlines, 64);
  EXPECT_LE(n.size(), 64u);
  EXPECT_EQ(n.substr(n.size() - 3), "...");
  EXPECT_EQ((n.size() - 3) % 2, 0u);  // whole "\n" pairs only
  const std::string accents = std::string(63, 'a') + kE + kE;
  const std::string a = untrusted_excerpt(accents, 64);
  EXPECT_TRUE(is_valid_utf8(a));
  EXPECT_LE(a.size(), 64u);
}

}  // namespace
}  // namespace fleetgw::common
