// PostgreSQL's COPY text format, as the ingest builds it straight from a decoded message
// (issue 25: one buffer per message's rows instead of a heap string per value) and reads it
// back on the rare paths that need single values (a redelivery's ON CONFLICT, latest values).
//
// Contract:
//  * A row is its values separated by a tab and ended by a newline; NULL is `\N`; inside a value
//    a backslash, tab, newline and carriage return are escaped (`\\`, `\t`, `\n`, `\r`), every
//    other byte (invalid UTF-8 included: the server judges it) kept as it is. So an unescaped
//    tab only separates values and an unescaped newline only ends rows.
//  * append_copy_text(out, v) appends v escaped; the escaped form is injective (two values are
//    equal exactly when their escaped forms are), so rows can be compared without unescaping.
//  * next_row(rows) takes the first row off `rows` (without its newline); split_row(row, out)
//    its values, still escaped; copy_value(v) one escaped value as it was (nullopt for `\N`).
//  * append_array_element(out, v) appends the escaped COPY value v as one element of a text[]
//    literal being built in `out` (which starts with `{`): NULL, or double-quoted with `"` and
//    `\` escaped, after undoing COPY's escapes.
//  * Pure functions, no allocation but the output's.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::ingest {

void append_copy_text(std::string& out, std::string_view v);
std::string_view next_row(std::string_view& rows);
void split_row(std::string_view row, std::vector<std::string_view>& out);
std::optional<std::string> copy_value(std::string_view v);
void append_array_element(std::string& out, std::string_view v);

}  // namespace fleetgw::ingest
