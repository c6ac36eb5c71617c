// Every check UplinkConfig::validate() applies, as a list of problems instead of a first-error
// throw: `fleetgw check-config` and `fleetgw run` report all of them, naming the fleetgw.toml key
// each value comes from, before any MQTT client exists.
//
// Contract: check_uplink_config() never throws and returns nothing for a config validate()
// accepts. Each problem names the UplinkConfig field and the configuration key it is set from
// ("mqtt.uri"; "uplink.<field>" for fields that fleetgw.toml does not expose). Messages never
// contain the password, and URIs are quoted without their user information.
#pragma once

#include <string>
#include <vector>

#include "gateway/uplink/uplink_config.h"

namespace fleetgw::uplink {

struct UplinkConfigProblem {
  std::string field;       // UplinkConfig member, e.g. "tls.ca_file"
  std::string config_key;  // fleetgw.toml key, e.g. "mqtt.ca_file"
  std::string message;     // what is wrong and what to do, naming real keys
};

std::vector<UplinkConfigProblem> check_uplink_config(const UplinkConfig& config);

// "mqtt.username (uplink.username): credentials over ...": one problem as one line, naming the
// configuration key first and the UplinkConfig field in brackets.
std::string describe(const UplinkConfigProblem& problem);

}  // namespace fleetgw::uplink
