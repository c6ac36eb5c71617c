#include "gateway/uplink/topics.h"

#include <cctype>
#include <stdexcept>

namespace fleetgw::uplink {

bool is_valid_vehicle_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char c : id) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') {
      return false;
    }
  }
  return true;
}

bool is_valid_topic_prefix(std::string_view prefix) {
  if (prefix.empty() || prefix.front() == '/' || prefix.back() == '/') return false;
  if (prefix.find("//") != std::string_view::npos) return false;
  for (const char c : prefix) {
    if (c == '+' || c == '#' || c == '\0') return false;
  }
  return true;
}

Topics::Topics(std::string_view prefix, std::string_view vehicle_id) {
  if (!is_valid_topic_prefix(prefix)) {
    throw std::invalid_argument("uplink.topic_prefix '" + std::string(prefix) +
                                "' is invalid: non-empty, no '+', '#', empty levels, or "
                                "leading/trailing '/'");
  }
  if (!is_valid_vehicle_id(vehicle_id)) {
    throw std::invalid_argument("uplink.vehicle_id '" + std::string(vehicle_id) +
                                "' is invalid: 1..64 characters of [A-Za-z0-9._-]");
  }
  base = std::string(prefix) + "/" + std::string(vehicle_id);
  for (const auto& t : kTopicTable) {
    this->*t.member = (t.fleet_wide ? std::string(prefix) : base) + "/" + std::string(t.leaf);
  }
}

const TopicSpec* find_topic(const Topics& topics, const std::string* topic) {
  for (const auto& t : kTopicTable) {
    if (&(topics.*t.member) == topic) return &t;
  }
  return nullptr;
}

std::vector<std::string> acl_patterns(std::string_view prefix) {
  std::vector<std::string> out;
  out.reserve(kTopicTable.size());
  for (const auto& t : kTopicTable) {
    out.push_back(std::string("pattern ") +
                  (t.direction == TopicDirection::kPublish ? "write " : "read ") +
                  std::string(prefix) + (t.fleet_wide ? "/" : "/%u/") + std::string(t.leaf));
  }
  return out;
}

}  // namespace fleetgw::uplink
