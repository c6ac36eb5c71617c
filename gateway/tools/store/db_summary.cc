#include "gateway/tools/store/db_summary.h"

#include <fmt/format.h>

#include <string_view>
#include <utility>

#include "gateway/tools/common/time_arg.h"
#include "motinova/can.h"

namespace fleetgw::tools {
// Named, not only anonymous: unity builds put this file in one translation unit with
// db_listings.cc, whose anonymous helpers have the same short names.
namespace summary_cli {
namespace {

using nlohmann::json;

const json* member(const json& row, const char* name) {
  if (!row.is_object()) return nullptr;
  const auto it = row.find(name);
  return it == row.end() || it->is_null() ? nullptr : &*it;
}

std::optional<std::string> text(const json& row, const char* name) {
  const json* v = member(row, name);
  if (v && v->is_string()) return v->get<std::string>();
  return std::nullopt;
}

std::optional<double> number(const json& row, const char* name) {
  const json* v = member(row, name);
  if (v && v->is_number()) return v->get<double>();
  return std::nullopt;
}

std::string node_name_of(const json& row) {
  const json* v = member(row, "node");
  if (!v || !v->is_number_integer()) return "node?";
  const auto n = v->get<std::int64_t>();
  if (n < 0 || n > 15) return "node" + std::to_string(n);
  return std::string(motinova::node_name(static_cast<motinova::Node>(n)));
}

// "1 ride" / "2 rides".
std::string count_of(std::uint64_t n, std::string_view one, std::string_view many) {
  return fmt::format("{} {}", n, n == 1 ? one : many);
}

// "interlock_moving" when one reason, "2 interlock_moving, 1 expired" when several.
std::string reasons_text(const std::map<std::string, std::uint64_t>& reasons) {
  if (reasons.empty()) return "";
  if (reasons.size() == 1) return reasons.begin()->first;
  std::string out;
  for (const auto& [reason, n] : reasons) {
    if (!out.empty()) out += ", ";
    out += fmt::format("{} {}", n, reason);
  }
  return out;
}

std::string alarm_words(std::string_view kind) {
  static constexpr std::pair<std::string_view, std::string_view> kWords[] = {
      {"unauthorised_movement", "theft"},
      {"lock_forced", "forced lock"},
      {"low_battery", "low battery"},
      {"battery_removed", "battery removed"},
      {"battery_swapped", "battery swapped"}};
  for (const auto& [k, words] : kWords) {
    if (k == kind) return std::string(words);
  }
  return std::string(kind);
}

std::string rides_text(const DbSummary& s) {
  if (s.rides == 0) return "no rides";
  std::string out = fmt::format("{}, {:.1f} km, {:.0f} min", count_of(s.rides, "ride", "rides"),
                                s.distance_km, s.duration_s / 60);
  if (s.rides_open > 0) out += fmt::format(" ({} open)", s.rides_open);
  return out;
}

std::string faults_text(const DbSummary& s) {
  if (s.faults_raised == 0 && s.faults_cleared == 0 && s.faults_unknown == 0) return "no faults";
  std::string out = fmt::format("{} raised, {} cleared",
                                count_of(s.faults_raised, "fault", "faults"), s.faults_cleared);
  if (s.faults_unknown > 0) out += fmt::format(", {} unknown", s.faults_unknown);
  return out;
}

std::uint64_t result_count(const DbSummary& s, const std::string& result) {
  const auto it = s.commands_by_result.find(result);
  return it == s.commands_by_result.end() ? 0 : it->second;
}

std::string commands_detail(const DbSummary& s) {
  std::vector<std::string> parts;
  if (const auto n = result_count(s, "succeeded")) parts.push_back(fmt::format("{} succeeded", n));
  if (const auto n = result_count(s, "rejected")) {
    parts.push_back(fmt::format("{} refused ({})", n, reasons_text(s.refused_by_reason)));
  }
  if (const auto n = result_count(s, "failed")) parts.push_back(fmt::format("{} failed", n));
  if (const auto n = result_count(s, "timeout")) parts.push_back(fmt::format("{} timed out", n));
  for (const auto& [result, n] : s.commands_by_result) {
    if (result == "succeeded" || result == "rejected" || result == "failed" ||
        result == "timeout") {
      continue;
    }
    parts.push_back(fmt::format("{} {}", n, result));
  }
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : ", ") + p;
  return out;
}

std::string commands_text(const DbSummary& s) {
  if (s.commands == 0) return "no commands";
  return count_of(s.commands, "command", "commands") + ": " + commands_detail(s);
}

std::string alarms_detail(const DbSummary& s) {
  std::map<std::string, std::uint64_t> by_words;
  for (const auto& [kind, n] : s.alarms_by_kind) by_words[alarm_words(kind)] += n;
  if (by_words.size() == 1) return by_words.begin()->first;
  std::string out;
  for (const auto& [words, n] : by_words) {
    out += fmt::format("{}{} {}", out.empty() ? "" : ", ", n, words);
  }
  return out;
}

std::string alarms_text(const DbSummary& s) {
  if (s.alarms_raised == 0) return "no alarms";
  return fmt::format("{} ({})", count_of(s.alarms_raised, "alarm", "alarms"), alarms_detail(s));
}

void add_ride(DbSummary& s, const json& r) {
  ++s.rides;
  if (text(r, "state") == "open") ++s.rides_open;
  if (number(r, "partial").value_or(0) != 0) ++s.rides_partial;
  const bool odometer = number(r, "start_odo_km") && number(r, "end_odo_km");
  s.distance_km += number(r, odometer ? "distance_km" : "distance_integrated_km").value_or(0);
  s.duration_s += number(r, "duration_s").value_or(0);
  s.moving_s += number(r, "moving_s").value_or(0);
  s.energy_wh += number(r, "energy_wh").value_or(0);
}

void add_fault(DbSummary& s, const json& f) {
  const auto event = text(f, "event").value_or("unknown");
  if (event == "raised") {
    ++s.faults_raised;
    ++s.raised_by_fault[node_name_of(f) + ":" + text(f, "name").value_or("?")];
  } else if (event == "cleared") {
    ++s.faults_cleared;
  } else {
    ++s.faults_unknown;
  }
}

// A result's reason is "code: detail for people" ("interlock_moving: will not lock the frame
// lock while the bike moves (speed 18.3 km/h ...)"): counted by its code.
std::string reason_code(const json& c) {
  const std::string reason = text(c, "reason").value_or("");
  const std::string code = reason.substr(0, reason.find(':'));
  return code.empty() ? "unspecified" : code;
}

void add_command(DbSummary& s, const json& c) {
  ++s.commands;
  const auto result = text(c, "result");
  const std::string key = result ? *result : text(c, "state").value_or("unknown");
  ++s.commands_by_result[key];
  if (key == "rejected") ++s.refused_by_reason[reason_code(c)];
  if (key == "failed" || key == "timeout") ++s.failed_by_reason[reason_code(c)];
}

void add_alarm(DbSummary& s, const json& a) {
  const auto transition = text(a, "transition").value_or("");
  if (transition == "raised") {
    ++s.alarms_raised;
    ++s.alarms_by_kind[text(a, "kind").value_or("unknown")];
  } else if (transition == "cleared") {
    ++s.alarms_cleared;
  }
}

json counts(const std::map<std::string, std::uint64_t>& m) {
  json j = json::object();
  for (const auto& [k, n] : m) j[k] = n;
  return j;
}

}  // namespace
}  // namespace summary_cli

DbSummary summarize(const SummaryRows& rows, std::optional<std::int64_t> since_us) {
  DbSummary s;
  s.since_us = since_us;
  for (const auto& r : rows.rides) summary_cli::add_ride(s, r);
  for (const auto& f : rows.faults) summary_cli::add_fault(s, f);
  for (const auto& c : rows.commands) summary_cli::add_command(s, c);
  for (const auto& a : rows.alarms) summary_cli::add_alarm(s, a);
  return s;
}

std::string summary_sentence(const DbSummary& s) {
  using namespace summary_cli;
  // The parts carry store strings (reasons, kinds) as stored; made printable once, here.
  return table_cell(rides_text(s) + "; " + faults_text(s) + "; " + commands_text(s) + "; " +
                    alarms_text(s));
}

nlohmann::json summary_json(const DbSummary& s) {
  using nlohmann::json;
  using summary_cli::counts;
  json j;
  j["since"] = s.since_us ? json(iso_utc(*s.since_us)) : json(nullptr);
  j["summary"] = summary_sentence(s);
  j["rides"] = {{"count", s.rides},
                {"open", s.rides_open},
                {"partial", s.rides_partial},
                {"distance_km", s.distance_km},
                {"duration_min", s.duration_s / 60},
                {"moving_min", s.moving_s / 60},
                {"energy_wh", s.energy_wh}};
  j["faults"] = {{"raised", s.faults_raised},
                 {"cleared", s.faults_cleared},
                 {"unknown", s.faults_unknown},
                 {"raised_by_fault", counts(s.raised_by_fault)}};
  j["commands"] = {{"count", s.commands},
                   {"by_result", counts(s.commands_by_result)},
                   {"refused_by_reason", counts(s.refused_by_reason)},
                   {"failed_by_reason", counts(s.failed_by_reason)}};
  j["alarms"] = {{"raised", s.alarms_raised},
                 {"cleared", s.alarms_cleared},
                 {"raised_by_kind", counts(s.alarms_by_kind)}};
  return j;
}

Table summary_table(const DbSummary& s) {
  using nlohmann::json;
  using namespace summary_cli;
  Table t;
  t.columns = {{"what", "WHAT"}, {"count", "COUNT"}, {"detail", "DETAIL"}};
  std::string ride_detail =
      s.rides == 0 ? "-"
                   : fmt::format(
                         "{:.2f} km, {:.1f} min ({:.1f} moving), {:.1f} Wh, {} open, {} "
                         "partial",
                         s.distance_km, s.duration_s / 60, s.moving_s / 60, s.energy_wh,
                         s.rides_open, s.rides_partial);
  t.rows.push_back({"rides", s.rides, ride_detail});
  std::string fault_detail;
  for (const auto& [fault, n] : s.raised_by_fault) {
    fault_detail += fmt::format("{}{} {}", fault_detail.empty() ? "" : ", ", n, fault);
  }
  fault_detail += fmt::format("{}{} cleared", fault_detail.empty() ? "" : "; ", s.faults_cleared);
  if (s.faults_unknown > 0) fault_detail += fmt::format(", {} unknown", s.faults_unknown);
  t.rows.push_back({"faults raised", s.faults_raised, fault_detail});
  t.rows.push_back(
      {"commands", s.commands, s.commands == 0 ? std::string("-") : commands_detail(s)});
  t.rows.push_back({"alarms raised", s.alarms_raised,
                    s.alarms_raised == 0
                        ? std::string("-")
                        : fmt::format("{}; {} cleared", alarms_detail(s), s.alarms_cleared)});
  return t;
}

}  // namespace fleetgw::tools
