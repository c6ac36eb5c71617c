#include "gateway/campaign/campaign_file.h"

#include <fmt/format.h>

#include <toml++/toml.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <ctime>
#include <iomanip>
#include <set>
#include <sstream>

#include "fleetgw/v1/campaign.pb.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::campaign {
namespace {

using json = nlohmann::json;

// A problem at `where`, thrown inside the converter and caught once.
struct FileProblem {
  std::string text;
};

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  throw FileProblem{where + ": " + what};
}

void only_keys(const json& obj, const std::string& where, std::set<std::string_view> known) {
  if (!obj.is_object()) fail(where.empty() ? "campaign" : where, "must be a table / object");
  for (const auto& [key, value] : obj.items()) {
    if (!known.contains(key)) {
      fail(where.empty() ? key : where + "." + key,
           "unknown key '" + common::untrusted_excerpt(key) + "'");
    }
  }
}

std::string path(const std::string& where, std::string_view key) {
  return where.empty() ? std::string(key) : where + "." + std::string(key);
}

std::string text_at(const json& obj, const std::string& where, std::string_view key) {
  const auto& v = obj.at(std::string(key));
  if (!v.is_string()) fail(path(where, key), "must be a string");
  return v.get<std::string>();
}

std::uint64_t unsigned_at(const json& obj, const std::string& where, std::string_view key) {
  const auto& v = obj.at(std::string(key));
  if (!v.is_number_integer() || v.get<std::int64_t>() < 0) {
    fail(path(where, key), "must be a non-negative integer");
  }
  return v.get<std::uint64_t>();
}

double number_at(const json& obj, const std::string& where, std::string_view key) {
  const auto& v = obj.at(std::string(key));
  if (!v.is_number()) fail(path(where, key), "must be a number");
  return v.get<double>();
}

std::vector<std::string> strings_at(const json& obj, const std::string& where,
                                    std::string_view key) {
  const auto& v = obj.at(std::string(key));
  if (!v.is_array()) fail(path(where, key), "must be an array of strings");
  std::vector<std::string> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!v[i].is_string()) fail(fmt::format("{}[{}]", path(where, key), i), "must be a string");
    out.push_back(v[i].get<std::string>());
  }
  return out;
}

// "2026-12-01T00:00:00Z" (or with a fraction / "+00:00") -> microseconds since the epoch.
std::int64_t rfc3339_us(const json& obj, const std::string& where, std::string_view key) {
  const std::string s = text_at(obj, where, key);
  std::tm tm{};
  std::istringstream in(s);
  in >> std::get_time(&tm, "%Y-%m-%dT%H:%M:%S");
  if (in.fail()) fail(path(where, key), "'" + common::untrusted_excerpt(s) + "' is not RFC 3339");
  std::string rest;
  std::getline(in, rest);
  if (!rest.empty() && rest[0] == '.') {
    rest.erase(0, rest.find_first_not_of("0123456789", 1));
  }
  if (rest != "Z" && rest != "+00:00") {
    fail(path(where, key), "'" + common::untrusted_excerpt(s) + "' must be UTC (Z)");
  }
  return static_cast<std::int64_t>(timegm(&tm)) * 1'000'000;
}

std::uint32_t day_seconds(const json& obj, const std::string& where, std::string_view key) {
  const std::string s = text_at(obj, where, key);
  unsigned h = 0, m = 0;
  char colon = 0;
  std::istringstream in(s);
  if (!(in >> h >> colon >> m) || colon != ':' || h > 24 || m > 59 || (h == 24 && m != 0)) {
    fail(path(where, key), "'" + common::untrusted_excerpt(s) + "' is not HH:MM");
  }
  return h * 3600 + m * 60;
}

template <typename Enum>
Enum enum_at(const json& obj, const std::string& where, std::string_view key,
             std::initializer_list<std::pair<std::string_view, Enum>> names) {
  const std::string s = text_at(obj, where, key);
  std::string known;
  for (const auto& [name, value] : names) {
    if (s == name) return value;
    known += known.empty() ? std::string(name) : ", " + std::string(name);
  }
  fail(path(where, key), "'" + common::untrusted_excerpt(s) + "' is not one of " + known);
}

void read_trigger(const json& t, v1::CampaignTrigger& out) {
  const std::string w = "trigger";
  only_keys(t, w,
            {"kind", "day_start", "day_end", "day_start_s", "day_end_s", "condition", "zone"});
  if (!t.contains("kind")) fail(w + ".kind", "missing");
  out.set_kind(
      enum_at<v1::CampaignTriggerKind>(t, w, "kind",
                                       {{"always", v1::CAMPAIGN_TRIGGER_KIND_ALWAYS},
                                        {"time_window", v1::CAMPAIGN_TRIGGER_KIND_TIME_WINDOW},
                                        {"condition", v1::CAMPAIGN_TRIGGER_KIND_CONDITION},
                                        {"zone", v1::CAMPAIGN_TRIGGER_KIND_ZONE}}));
  if (t.contains("zone")) out.set_zone(text_at(t, w, "zone"));
  if (t.contains("day_start")) out.set_day_start_s(day_seconds(t, w, "day_start"));
  if (t.contains("day_end")) out.set_day_end_s(day_seconds(t, w, "day_end"));
  if (t.contains("day_start_s")) {
    out.set_day_start_s(static_cast<std::uint32_t>(unsigned_at(t, w, "day_start_s")));
  }
  if (t.contains("day_end_s")) {
    out.set_day_end_s(static_cast<std::uint32_t>(unsigned_at(t, w, "day_end_s")));
  }
  if (t.contains("condition")) {
    const auto& c = t.at("condition");
    const std::string cw = "trigger.condition";
    only_keys(c, cw, {"kind", "signal", "threshold", "hysteresis"});
    auto* cond = out.mutable_condition();
    if (!c.contains("kind")) fail(cw + ".kind", "missing");
    cond->set_kind(enum_at<v1::CampaignConditionKind>(
        c, cw, "kind",
        {{"above", v1::CAMPAIGN_CONDITION_KIND_ABOVE},
         {"below", v1::CAMPAIGN_CONDITION_KIND_BELOW},
         {"rising_edge", v1::CAMPAIGN_CONDITION_KIND_RISING_EDGE},
         {"falling_edge", v1::CAMPAIGN_CONDITION_KIND_FALLING_EDGE},
         {"fault_active", v1::CAMPAIGN_CONDITION_KIND_FAULT_ACTIVE}}));
    if (c.contains("signal")) cond->set_signal(text_at(c, cw, "signal"));
    // Numbers in the signal's unit; the wire carries them times 10^6 (campaign.proto).
    auto e6 = [&](std::string_view key) {
      const double v = number_at(c, cw, key);
      if (!std::isfinite(v) || std::fabs(v) > 9.0e12) fail(path(cw, key), "out of range");
      return static_cast<std::int64_t>(std::llround(v * 1e6));
    };
    if (c.contains("threshold")) cond->set_threshold_e6(e6("threshold"));
    if (c.contains("hysteresis")) {
      const auto h = e6("hysteresis");
      if (h < 0) fail(cw + ".hysteresis", "must be >= 0");
      cond->set_hysteresis_e6(static_cast<std::uint64_t>(h));
    }
  }
}

void read_sampling(const json& s, v1::CampaignSampling& out) {
  const std::string w = "sampling";
  only_keys(s, w, {"kind", "period_ms", "before_ms", "after_ms"});
  if (!s.contains("kind")) fail(w + ".kind", "missing");
  out.set_kind(
      enum_at<v1::CampaignSamplingKind>(s, w, "kind",
                                        {{"every", v1::CAMPAIGN_SAMPLING_KIND_EVERY},
                                         {"on_change", v1::CAMPAIGN_SAMPLING_KIND_ON_CHANGE},
                                         {"window", v1::CAMPAIGN_SAMPLING_KIND_WINDOW}}));
  auto u32 = [&](std::string_view key) {
    const auto v = unsigned_at(s, w, key);
    if (v > UINT32_MAX) fail(path(w, key), "too large");
    return static_cast<std::uint32_t>(v);
  };
  if (s.contains("period_ms")) out.set_period_ms(u32("period_ms"));
  if (s.contains("before_ms")) out.set_before_ms(u32("before_ms"));
  if (s.contains("after_ms")) out.set_after_ms(u32("after_ms"));
}

void read_target(const json& t, v1::CampaignTarget& out) {
  const std::string w = "target";
  only_keys(t, w, {"vehicle_ids", "groups", "all_vehicles", "firmware"});
  if (t.contains("vehicle_ids")) {
    for (auto& v : strings_at(t, w, "vehicle_ids")) out.add_vehicle_ids(v);
  }
  if (t.contains("groups")) {
    for (auto& g : strings_at(t, w, "groups")) out.add_groups(g);
  }
  if (t.contains("all_vehicles")) {
    if (!t.at("all_vehicles").is_boolean()) fail(w + ".all_vehicles", "must be true or false");
    out.set_all_vehicles(t.at("all_vehicles").get<bool>());
  }
  if (t.contains("firmware")) {
    const auto& list = t.at("firmware");
    if (!list.is_array()) fail(w + ".firmware", "must be an array of tables");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string fw = fmt::format("{}.firmware[{}]", w, i);
      only_keys(list[i], fw, {"node", "versions", "prefix"});
      auto* f = out.add_firmware();
      if (list[i].contains("node")) f->set_node(text_at(list[i], fw, "node"));
      if (list[i].contains("versions")) {
        for (auto& v : strings_at(list[i], fw, "versions")) f->add_versions(v);
      }
      if (list[i].contains("prefix")) f->set_prefix(text_at(list[i], fw, "prefix"));
    }
  }
}

v1::Campaign from_json(const json& j) {
  v1::Campaign c;
  only_keys(j, "",
            {"id", "version", "description", "signals", "trigger", "sampling", "priority",
             "disk_budget_bytes", "start", "end", "start_us", "end_us", "target"});
  for (const auto* required : {"id", "signals", "trigger", "sampling", "target"}) {
    if (!j.contains(required)) fail(required, "missing");
  }
  c.set_id(text_at(j, "", "id"));
  if (j.contains("version")) c.set_version(unsigned_at(j, "", "version"));
  if (j.contains("description")) c.set_description(text_at(j, "", "description"));
  for (auto& s : strings_at(j, "", "signals")) c.add_signals(s);
  read_trigger(j.at("trigger"), *c.mutable_trigger());
  read_sampling(j.at("sampling"), *c.mutable_sampling());
  if (j.contains("priority"))
    c.set_priority(static_cast<std::uint32_t>(unsigned_at(j, "", "priority")));
  if (j.contains("disk_budget_bytes"))
    c.set_disk_budget_bytes(unsigned_at(j, "", "disk_budget_bytes"));
  if (j.contains("start")) c.set_start_us(rfc3339_us(j, "", "start"));
  if (j.contains("end")) c.set_end_us(rfc3339_us(j, "", "end"));
  if (j.contains("start_us"))
    c.set_start_us(static_cast<std::int64_t>(unsigned_at(j, "", "start_us")));
  if (j.contains("end_us")) c.set_end_us(static_cast<std::int64_t>(unsigned_at(j, "", "end_us")));
  read_target(j.at("target"), *c.mutable_target());
  return c;
}

}  // namespace

std::variant<v1::Campaign, std::string> parse_campaign_text(std::string_view text,
                                                            std::string_view source_name) {
  const std::string name(source_name);
  json doc;
  const auto first = text.find_first_not_of(" \t\r\n");
  try {
    if (first != std::string_view::npos && text[first] == '{') {
      doc = json::parse(text);
    } else {
      const toml::table table = toml::parse(text, source_name);
      std::ostringstream as_json;
      as_json << toml::json_formatter{table};
      doc = json::parse(as_json.str());
    }
  } catch (const toml::parse_error& e) {
    return fmt::format("{}:{}:{}: {}", name, e.source().begin.line, e.source().begin.column,
                       e.description());
  } catch (const json::exception& e) {
    return name + ": not JSON: " + e.what();
  }
  try {
    return from_json(doc);
  } catch (const FileProblem& p) {
    return name + ": " + p.text;
  }
}

}  // namespace fleetgw::campaign
