// A small checker of the XML subset the `fleetgw ride plot` SVG builder writes (prolog, elements,
// double-quoted attributes, text, the five entities), shared by the builder's unit tests
// (test_ride_plot.cc, test_ride_plot_map.cc).
#pragma once

#include <cctype>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/common/untrusted_text.h"

namespace fleetgw::testing {

// "" when `doc` is well-formed XML as far as the builder's subset goes (prolog, elements,
// double-quoted attributes, text, the five entities), else what is wrong and where.
inline std::string xml_problem(std::string_view doc) {
  if (!common::is_valid_utf8(doc)) return "invalid UTF-8";
  std::vector<std::string> open;
  bool root_closed = false;
  std::size_t i = 0;
  if (doc.starts_with("<?xml")) {
    i = doc.find("?>");
    if (i == std::string_view::npos) return "unterminated prolog";
    i += 2;
  }
  const auto is_name_char = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == ':' || c == '_';
  };
  const auto entity_ok = [&](std::size_t at) {
    for (std::string_view e : {"&amp;", "&lt;", "&gt;", "&quot;", "&apos;"}) {
      if (doc.substr(at, e.size()) == e) return e.size();
    }
    return std::size_t{0};
  };
  while (i < doc.size()) {
    const char c = doc[i];
    if (static_cast<unsigned char>(c) < 0x20 && c != '\n') {
      return "control character at " + std::to_string(i);
    }
    if (c == '&') {
      const auto n = entity_ok(i);
      if (n == 0) return "bare & at " + std::to_string(i);
      i += n;
      continue;
    }
    if (c == '>') return "bare > at " + std::to_string(i);
    if (c != '<') {
      if (open.empty() && c != '\n') return "text outside the root at " + std::to_string(i);
      ++i;
      continue;
    }
    const bool closing = i + 1 < doc.size() && doc[i + 1] == '/';
    std::size_t j = i + (closing ? 2 : 1);
    const std::size_t name_start = j;
    while (j < doc.size() && is_name_char(doc[j])) ++j;
    const std::string name(doc.substr(name_start, j - name_start));
    if (name.empty()) return "tag without a name at " + std::to_string(i);
    if (closing) {
      if (j >= doc.size() || doc[j] != '>') return "bad closing tag at " + std::to_string(i);
      if (open.empty() || open.back() != name) return "mismatched </" + name + ">";
      open.pop_back();
      if (open.empty()) root_closed = true;
      i = j + 1;
      continue;
    }
    if (root_closed || (open.empty() && name != "svg")) return "second root <" + name + ">";
    // Attributes: ( space name="value" )*, then > or />.
    while (true) {
      if (j >= doc.size()) return "unterminated <" + name + ">";
      if (doc[j] == '>' || doc.substr(j, 2) == "/>") break;
      if (doc[j] != ' ') return "expected a space in <" + name + "> at " + std::to_string(j);
      ++j;
      const std::size_t attr = j;
      while (j < doc.size() && is_name_char(doc[j])) ++j;
      if (j == attr || doc.substr(j, 2) != "=\"") return "bad attribute in <" + name + ">";
      j += 2;
      while (j < doc.size() && doc[j] != '"') {
        if (doc[j] == '<' || static_cast<unsigned char>(doc[j]) < 0x20) {
          return "bad character in an attribute of <" + name + ">";
        }
        if (doc[j] == '&') {
          const auto n = entity_ok(j);
          if (n == 0) return "bare & in an attribute of <" + name + ">";
          j += n;
        } else {
          ++j;
        }
      }
      if (j >= doc.size()) return "unterminated attribute in <" + name + ">";
      ++j;
    }
    if (doc[j] == '>') {
      open.push_back(name);
      i = j + 1;
    } else {
      if (open.empty()) root_closed = true;
      i = j + 2;
    }
  }
  if (!open.empty()) return "unclosed <" + open.back() + ">";
  if (!root_closed) return "no root element";
  return "";
}

}  // namespace fleetgw::testing
