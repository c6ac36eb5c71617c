#include "gateway/common/table_format.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "gateway/common/untrusted_text.h"

namespace fleetgw::common {
namespace {

using nlohmann::json;

// Code points, not bytes: the table is aligned as a terminal shows it (wide characters aside).
std::size_t display_width(std::string_view s) {
  std::size_t n = 0;
  for (const char c : s) {
    if ((static_cast<unsigned char>(c) & 0xC0) != 0x80) ++n;
  }
  return n;
}

std::string format_double(double v, int decimals) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  if (decimals < 0) return json(v).dump();
  return fmt::format("{:.{}f}", v, decimals);
}

double round_to(double v, int decimals) {
  if (decimals < 0 || !std::isfinite(v)) return v;
  const double scale = std::pow(10.0, decimals);
  return std::round(v * scale) / scale;
}

std::string table_text(const json& cell, int decimals) {
  if (cell.is_null()) return "-";
  if (cell.is_boolean()) return cell.get<bool>() ? "yes" : "no";
  if (cell.is_number_float()) return format_double(cell.get<double>(), decimals);
  if (cell.is_number()) return cell.dump();
  if (cell.is_string()) return table_cell(cell.get_ref<const std::string&>());
  return table_cell(cell.dump(-1, ' ', false, json::error_handler_t::replace));
}

std::string csv_text(const json& cell, int decimals) {
  if (cell.is_null()) return "";
  if (cell.is_boolean()) return cell.get<bool>() ? "true" : "false";
  if (cell.is_number_float()) return format_double(cell.get<double>(), decimals);
  if (cell.is_number()) return cell.dump();
  if (cell.is_string()) return csv_field(cell.get_ref<const std::string&>());
  return csv_field(cell.dump(-1, ' ', false, json::error_handler_t::replace));
}

void flatten_into(const json& value, const std::string& key, Table& t) {
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it) {
      flatten_into(it.value(), key.empty() ? it.key() : key + "." + it.key(), t);
    }
  } else if (value.is_array()) {
    for (std::size_t i = 0; i < value.size(); ++i) {
      flatten_into(value[i], key + "." + std::to_string(i), t);
    }
  } else {
    t.rows.push_back({key, value});
  }
}

}  // namespace

std::optional<OutputFormat> parse_output_format(std::string_view text) {
  if (text == "table") return OutputFormat::kTable;
  if (text == "json") return OutputFormat::kJson;
  if (text == "csv") return OutputFormat::kCsv;
  return std::nullopt;
}

std::string table_cell(std::string_view text) {
  return escape_controls(text);
}

std::string csv_field(std::string_view text) {
  std::string valid = valid_utf8(text);
  // OWASP's CSV-injection rule: a spreadsheet runs a cell that starts with = + - @ TAB or CR as
  // a formula (`=cmd|'/Ccalc'!A0` in a BMS serial starts a program). Such text gets a leading ',
  // which makes it text; so does text that already starts with ', so that removing one leading '
  // from every text cell that has one gives the stored string back (no ambiguity).
  bool quote = false;
  if (!valid.empty() &&
      std::string_view("=+-@\t\r'").find(valid.front()) != std::string_view::npos) {
    valid.insert(valid.begin(), '\'');
    quote = true;  // as OWASP asks: the cell quoted, so no reader splits or trims it
  }
  for (const char c : valid) {
    const auto u = static_cast<unsigned char>(c);
    if (c == ',' || c == '"' || u < 0x20 || u == 0x7F) quote = true;
  }
  if (!quote) return valid;
  std::string out = "\"";
  for (const char c : valid) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
  return out;
}

void write_table(const Table& t, std::ostream& out) {
  if (t.rows.empty()) {
    out << "(no rows)\n";
    return;
  }
  const std::size_t ncol = t.columns.size();
  std::vector<std::vector<std::string>> text(t.rows.size(), std::vector<std::string>(ncol));
  std::vector<std::size_t> width(ncol);
  std::vector<bool> numeric(ncol, true);
  for (std::size_t c = 0; c < ncol; ++c) width[c] = display_width(t.columns[c].header);
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    for (std::size_t c = 0; c < ncol; ++c) {
      const json& cell = c < t.rows[r].size() ? t.rows[r][c] : json();
      if (!cell.is_null() && !cell.is_number()) numeric[c] = false;
      text[r][c] = table_text(cell, t.columns[c].decimals);
      width[c] = std::max(width[c], display_width(text[r][c]));
    }
  }
  auto line = [&](const auto& cell_of) {
    std::string s;
    for (std::size_t c = 0; c < ncol; ++c) {
      const std::string& cell = cell_of(c);
      const std::string pad(width[c] - display_width(cell), ' ');
      if (c > 0) s += "  ";
      if (numeric[c]) {
        s += pad + cell;
      } else {
        s += cell;
        if (c + 1 < ncol) s += pad;  // no trailing blanks
      }
    }
    out << s << '\n';
  };
  line([&](std::size_t c) -> const std::string& { return t.columns[c].header; });
  for (const auto& row : text) line([&](std::size_t c) -> const std::string& { return row[c]; });
}

void write_csv_header(const std::vector<Column>& columns, std::ostream& out) {
  for (std::size_t c = 0; c < columns.size(); ++c) {
    out << (c ? "," : "") << csv_field(columns[c].key);
  }
  out << "\r\n";
}

void write_csv_record(const std::vector<Column>& columns, const std::vector<json>& row,
                      std::ostream& out) {
  for (std::size_t c = 0; c < columns.size(); ++c) {
    out << (c ? "," : "") << csv_text(c < row.size() ? row[c] : json(), columns[c].decimals);
  }
  out << "\r\n";
}

void write_csv(const Table& t, std::ostream& out) {
  write_csv_header(t.columns, out);
  for (const auto& row : t.rows) write_csv_record(t.columns, row, out);
}

void write_json(const Table& t, std::ostream& out) {
  out << '[';
  for (std::size_t r = 0; r < t.rows.size(); ++r) {
    json obj = json::object();
    for (std::size_t c = 0; c < t.columns.size(); ++c) {
      json cell = c < t.rows[r].size() ? t.rows[r][c] : json();
      if (cell.is_number_float()) cell = round_to(cell.get<double>(), t.columns[c].decimals);
      obj[t.columns[c].key] = std::move(cell);
    }
    out << (r ? ",\n" : "\n") << obj.dump(-1, ' ', false, json::error_handler_t::replace);
  }
  out << (t.rows.empty() ? "]\n" : "\n]\n");
}

void write_as(OutputFormat format, const Table& t, std::ostream& out) {
  switch (format) {
    case OutputFormat::kTable:
      write_table(t, out);
      break;
    case OutputFormat::kJson:
      write_json(t, out);
      break;
    case OutputFormat::kCsv:
      write_csv(t, out);
      break;
  }
}

Table flatten(const nlohmann::json& doc) {
  Table t;
  t.columns = {{"key", "KEY", -1}, {"value", "VALUE", -1}};
  flatten_into(doc, "", t);
  return t;
}

}  // namespace fleetgw::common
