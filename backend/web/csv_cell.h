// One CSV cell of text for the console's downloads (the campaign page's samples.csv).
#pragma once

#include <string>
#include <string_view>

namespace fleetgw::web {

// One CSV cell of text under the product's formula rule (the backend's copy of the gateway's
// common::csv_field, docs/storage.md "CSV is safe to open in a spreadsheet"): text starting
// with = + - @ TAB CR (or ') gets a leading ' and is quoted, so a spreadsheet shows it as text
// and never runs it; a cell holding , " CR LF or another control character is quoted.
inline std::string csv_text_cell(std::string_view text) {
  std::string v(text);
  bool quote = false;
  if (!v.empty() && std::string_view("=+-@\t\r'").find(v.front()) != std::string_view::npos) {
    v.insert(v.begin(), '\'');
    quote = true;
  }
  for (const char ch : v) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == ',' || ch == '"' || u < 0x20 || u == 0x7F) quote = true;
  }
  if (!quote) return v;
  std::string out = "\"";
  for (const char ch : v) {
    if (ch == '"') out += '"';
    out += ch;
  }
  return out + "\"";
}

}  // namespace fleetgw::web
