// Reading a number from a scenario's TOML: one rule for the scenario reader (scenario.cc) and
// the route's waypoints (route.cc), so both accept the same values and word errors alike.
//
// Contract:
//  * read_number() accepts a TOML integer or float that is finite and within lo..hi, and returns
//    it as a double. Anything else throws ScenarioError naming `file`, the value's line and
//    `key`: "expected a number, got a string", "expected a number in 0..60, got 75".
//  * toml_type_name() is the article-and-noun a message uses for a value's type ("a string").
#pragma once

#include <string>

#include <toml++/toml.h>

namespace fleetgw::sim {

double read_number(const toml::node& node, double lo, double hi, const std::string& file,
                   const std::string& key);

std::string toml_type_name(const toml::node& node);

}  // namespace fleetgw::sim
