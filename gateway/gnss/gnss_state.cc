#include "gateway/gnss/gnss_state.h"

#include <cmath>

namespace fleetgw::gnss {

double distance_m(double lat1_deg, double lon1_deg, double lat2_deg, double lon2_deg) {
  constexpr double kEarthRadiusM = 6'371'008.8;  // IUGG mean radius
  constexpr double kRad = M_PI / 180.0;
  const double dlat = (lat2_deg - lat1_deg) * kRad;
  const double dlon = (lon2_deg - lon1_deg) * kRad;
  const double a = std::sin(dlat / 2) * std::sin(dlat / 2) +
                   std::cos(lat1_deg * kRad) * std::cos(lat2_deg * kRad) * std::sin(dlon / 2) *
                       std::sin(dlon / 2);
  return 2 * kEarthRadiusM * std::asin(std::min(1.0, std::sqrt(a)));
}

void GnssState::on_fix(const Position& fix) {
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

std::optional<Position> GnssState::current(Micros now) const {
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
