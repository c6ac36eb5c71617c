// Output of the inspection commands (`fleetgw db ...`, `fleetgw status`, the summary of
// `fleetgw decode`) in the three forms of `--format table|json|csv`, all from one Table. In
// fleetgw_common so that every area (decode as well as app) prints with the same writers.
//
// Contract:
//  * A Table is its columns (key for JSON and CSV, header for the aligned table, decimals for
//    floating-point cells) and rows of cells, each an nlohmann::json null, boolean, number or
//    string. Rows are printed in the order given.
//  * table: a header line, then exactly one line per row; columns separated by two spaces and
//    padded to the widest cell (counted in code points); numbers right-aligned, floating point
//    with the column's decimals; null is "-", booleans "yes"/"no". Strings come from the store
//    and are untrusted: every one passes escape_controls (untrusted_text.h), so a newline, tab, ESC
//    or any other control character (C0, DEL, C1, U+2028/9) prints as \n, \t, \x1b..., a backslash
//    as
//    \\, invalid UTF-8 as U+FFFD, and a row can never take more than one line. No rows: the
//    line "(no rows)" alone.
//  * csv: RFC 4180. A header line of the column keys, CRLF after every record; a field is
//    quoted ("...", an inner quote doubled) when it contains a comma, a quote, CR, LF or any
//    other control character. Text is neutralised against CSV injection (OWASP), here in
//    csv_field() and nowhere else: a string cell that starts with =, +, -, @, TAB or CR (which
//    a spreadsheet would run as a formula) or with ' gets one leading ' and is quoted. Otherwise
//    the content is kept exactly (only invalid UTF-8 is replaced by U+FFFD): a CSV reader gets
//    the stored string back, newlines included, by removing one leading ' from a text cell that
//    starts with one. Numbers are never altered (-3.5 stays -3.5): the rule is for strings.
//    Null is an empty field; floating point with the column's decimals; booleans true/false.
//  * json: one JSON array, one object per row (column key -> value) on its own line; floating
//    point rounded to the column's decimals; invalid UTF-8 replaced by U+FFFD.
//  * parse_output_format() accepts exactly "table", "json" and "csv".
#pragma once

#include <nlohmann/json.hpp>

#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::common {

enum class OutputFormat { kTable, kJson, kCsv };

std::optional<OutputFormat> parse_output_format(std::string_view text);

struct Column {
  std::string key;     // JSON member and CSV header: snake_case with the unit, e.g. distance_km
  std::string header;  // table header, e.g. "KM"
  int decimals = 1;    // for floating-point cells
};

struct Table {
  std::vector<Column> columns;
  std::vector<std::vector<nlohmann::json>> rows;  // each row has columns.size() cells
};

void write_table(const Table& t, std::ostream& out);
void write_csv(const Table& t, std::ostream& out);
// The two halves of write_csv, for writers that stream rows (`db export --format csv`): the
// header record of the column keys, and one record of `row` (cells as above).
void write_csv_header(const std::vector<Column>& columns, std::ostream& out);
void write_csv_record(const std::vector<Column>& columns, const std::vector<nlohmann::json>& row,
                      std::ostream& out);
void write_json(const Table& t, std::ostream& out);
void write_as(OutputFormat format, const Table& t, std::ostream& out);

// One CSV field of text (RFC 4180 quoting and the formula neutralisation above), without the
// separator. Every CSV writer of the product goes through it.
std::string csv_field(std::string_view text);
// One table cell's text: escape_controls of valid UTF-8.
std::string table_cell(std::string_view text);

// A JSON document as a two-column table (key, value): nested members flattened to dotted keys
// ("outbox.in_flight"), array elements to their index ("attention.0"); empty objects and
// arrays are left out. For `db stats`, `status` and the decode summary in table and CSV form.
Table flatten(const nlohmann::json& doc);

}  // namespace fleetgw::common
