#include "motinova/can.h"

#include <array>

namespace motinova {
namespace {
constexpr std::array<std::string_view, 16> kNames{
    "all",   "mc",    "bms",   "obc",   "hmi",    "cdl",    "iot",    "lock1",
    "lock2", "lock3", "lock4", "lock5", "node12", "node13", "node14", "node15"};
}

std::string_view node_name(Node n) {
  return kNames[static_cast<unsigned>(n) & 0xF];
}

std::optional<Node> node_from_name(std::string_view name) {
  for (unsigned i = 0; i < kNames.size(); ++i) {
    if (kNames[i] == name) return static_cast<Node>(i);
  }
  return std::nullopt;
}

}  // namespace motinova
