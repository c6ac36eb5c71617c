#include "gateway/sim/toml_number.h"

#include <cmath>
#include <cstdint>
#include <sstream>

#include "gateway/sim/scenario.h"

namespace fleetgw::sim {
namespace {

std::string format_number(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

}  // namespace

double read_number(const toml::node& node, double lo, double hi, const std::string& file,
                   const std::string& key) {
  const std::size_t line = node.source().begin.line;
  double v = 0;
  if (const auto i = node.value_exact<int64_t>()) {
    v = static_cast<double>(*i);
  } else if (const auto d = node.value_exact<double>()) {
    v = *d;
  } else {
    throw ScenarioError(file, line, key, "expected a number, got " + toml_type_name(node));
  }
  if (!std::isfinite(v) || v < lo || v > hi) {
    throw ScenarioError(file, line, key,
                        "expected a number in " + format_number(lo) + ".." + format_number(hi) +
                            ", got " + format_number(v));
  }
  return v;
}

std::string toml_type_name(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a float";
    case toml::node_type::boolean:
      return "a boolean";
    case toml::node_type::table:
      return "a table";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::date:
    case toml::node_type::time:
    case toml::node_type::date_time:
      return "a date/time";
    default:
      return "something else";
  }
}

}  // namespace fleetgw::sim
