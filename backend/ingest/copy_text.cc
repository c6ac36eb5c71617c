// COPY text format (copy_text.h).
#include "backend/ingest/copy_text.h"

#include <algorithm>
#include <cstring>

namespace fleetgw::ingest {
namespace {

char unescaped(char c) {
  switch (c) {
    case 't':
      return '\t';
    case 'n':
      return '\n';
    case 'r':
      return '\r';
    default:
      return c;  // `\\` (and anything else this file never writes) is the byte itself
  }
}

}  // namespace

void append_copy_text(std::string& out, std::string_view v) {
  // Runs without a special byte are appended whole (a byte at a time was a visible share of the
  // worker's profile).
  std::size_t run = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const char c = v[i];
    if (c != '\\' && c != '\t' && c != '\n' && c != '\r') continue;
    out.append(v.data() + run, i - run);
    out += '\\';
    out += c == '\t' ? 't' : c == '\n' ? 'n' : c == '\r' ? 'r' : '\\';
    run = i + 1;
  }
  out.append(v.data() + run, v.size() - run);
}

std::string_view next_row(std::string_view& rows) {
  const void* nl = std::memchr(rows.data(), '\n', rows.size());
  const std::size_t end =
      nl == nullptr ? rows.size() : static_cast<std::size_t>(static_cast<const char*>(nl) - rows.data());
  const std::string_view row = rows.substr(0, end);
  rows.remove_prefix(std::min(rows.size(), end + 1));
  return row;
}

void split_row(std::string_view row, std::vector<std::string_view>& out) {
  out.clear();
  for (;;) {
    const std::size_t tab = row.find('\t');
    out.push_back(row.substr(0, tab));
    if (tab == std::string_view::npos) return;
    row.remove_prefix(tab + 1);
  }
}

std::optional<std::string> copy_value(std::string_view v) {
  if (v == "\\N") return std::nullopt;
  std::string out;
  out.reserve(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] == '\\' && i + 1 < v.size()) {
      out += unescaped(v[++i]);
    } else {
      out += v[i];
    }
  }
  return out;
}

void append_array_element(std::string& out, std::string_view v) {
  if (out.size() > 1) out += ',';
  if (v == "\\N") {
    out += "NULL";
    return;
  }
  out += '"';
  std::size_t run = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const char c = v[i];
    if (c != '\\' && c != '"') continue;
    out.append(v.data() + run, i - run);
    if (c == '"') {
      out += "\\\"";
      run = i + 1;
      continue;
    }
    // A COPY escape: the byte it stands for, itself escaped for the array when it is a `\`.
    const char b = i + 1 < v.size() ? unescaped(v[++i]) : '\\';
    if (b == '\\' || b == '"') out += '\\';
    out += b;
    run = i + 1;
  }
  out.append(v.data() + run, v.size() - run);
  out += '"';
}

}  // namespace fleetgw::ingest
