#include "gateway/gnss/gnss_state.h"

#include <cmath>

namespace fleetgw::gnss {

void GnssState::on_fix(const Fix& fix) {
  source_ = Source::kConnected;
  fix_valid_ = true;
  last_ = fix;
  ++fixes_;
}

void GnssState::on_no_fix(Micros) {
  source_ = Source::kConnected;
  fix_valid_ = false;
}

void GnssState::on_source_lost(Micros) {
  source_ = Source::kLost;
  fix_valid_ = false;
}

void GnssState::on_source_connected(Micros) {
  // A new connection says nothing about the fix yet: keep "unknown" until a report arrives.
  source_ = Source::kConnected;
  fix_valid_ = false;
}

std::optional<Fix> GnssState::current(Micros now) const {
  if (!fix_valid_ || !last_ || source_ != Source::kConnected) return std::nullopt;
  if (now - last_->received_at > options_.max_age) return std::nullopt;
  return last_;
}

std::string_view GnssState::reason(Micros now) const {
  if (source_ == Source::kNeverConnected) return "gpsd not connected";
  if (source_ == Source::kLost) return "gpsd unreachable";
  if (!fix_valid_ || !last_) return "no fix";
  if (now - last_->received_at > options_.max_age) return "fix stale";
  return {};
}

std::optional<Micros> GnssState::next_change(Micros now) const {
  if (!current(now)) return std::nullopt;
  return last_->received_at + options_.max_age + Micros(1);
}

}  // namespace fleetgw::gnss
