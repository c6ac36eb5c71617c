#include "gateway/domain/ride_tracker.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <spdlog/spdlog.h>

#include "motinova/can.h"
#include "storage/track_text.h"

namespace fleetgw::domain {
namespace {

constexpr double kHour = 3600.0;
// Two 0.1 km steps: one step can be the quantisation of a bike pushed a few metres.
constexpr double kCounterStartKm = 0.15;
// Parked baselines are renewed this often, so slow drift (a bike nudged every day) never adds up.
constexpr Micros kParkedBaselineAge = std::chrono::minutes(10);
constexpr Micros kTripTimeWindow = std::chrono::seconds(60);
constexpr Micros kSocFresh = std::chrono::seconds(10);

double seconds(Micros d) {
  return static_cast<double>(d.count()) / 1e6;
}
Micros from_seconds(double s) {
  return Micros(static_cast<int64_t>(std::llround(s * 1e6)));
}
std::optional<int> whole_percent(std::optional<double> v) {
  if (!v) return std::nullopt;
  return static_cast<int>(std::lround(*v));
}

bool on_earth(const std::optional<double>& lat, const std::optional<double>& lon) {
  return lat && lon && std::fabs(*lat) <= 90.0 && std::fabs(*lon) <= 180.0;
}

// The track a previous run checkpointed in the ride row, so a ride resumed (or closed) after a
// restart keeps where it went before it. The row comes from a file that may be damaged or
// edited: columns that do not form a track are dropped (said in the log), never trusted.
void resume_track(storage::RideRow& rec, RideTrack& track) {
  if (!rec.start_lat_deg && !rec.start_lon_deg && !rec.track) return;  // no fix before
  std::string problem;
  storage::ParsedTrack parsed;
  if (!on_earth(rec.start_lat_deg, rec.start_lon_deg) ||
      !on_earth(rec.end_lat_deg, rec.end_lon_deg)) {
    problem = "start or end position missing or out of range";
  } else if (!rec.gnss_distance_m || !(*rec.gnss_distance_m >= 0) ||
             !std::isfinite(*rec.gnss_distance_m)) {
    problem = "gnss_distance_m missing or invalid";
  } else if (!rec.track) {
    problem = "track missing";
  } else if (parsed = storage::parse_track_text(*rec.track); !parsed.ok()) {
    problem = "track: " + parsed.error;
  }
  if (!problem.empty()) {
    spdlog::warn("rides: ride '{}' resumed without its positions before the restart ({})",
                 rec.ride_id, problem);
    rec.start_lat_deg.reset();
    rec.start_lon_deg.reset();
    rec.end_lat_deg.reset();
    rec.end_lon_deg.reset();
    rec.gnss_distance_m.reset();
    rec.track.reset();
    return;
  }
  auto at = [](double lat, double lon) {
    gnss::Fix p;
    p.lat_deg = lat;
    p.lon_deg = lon;
    return p;
  };
  std::vector<gnss::Fix> vertices;
  vertices.reserve(parsed.points.size());
  for (const auto& p : parsed.points) vertices.push_back(at(p.lat_deg, p.lon_deg));
  track.resume(at(*rec.start_lat_deg, *rec.start_lon_deg), at(*rec.end_lat_deg, *rec.end_lon_deg),
               *rec.gnss_distance_m, std::move(vertices));
}

}  // namespace

RideTracker::RideTracker(RideConfig config, DomainSink& sink)
    : config_(std::move(config)), sink_(sink) {}

void RideTracker::restore(std::span<const storage::RideRow> open_rides, Micros now) {
  if (open_) throw std::logic_error("RideTracker::restore: a ride is already open");
  if (open_rides.empty()) return;
  const auto newest = std::max_element(
      open_rides.begin(), open_rides.end(),
      [](const storage::RideRow& a, const storage::RideRow& b) { return a.start_us < b.start_us; });
  for (auto it = open_rides.begin(); it != open_rides.end(); ++it) {
    if (it == newest) continue;
    // An older open ride means a ride was never closed: close it where it was last seen.
    Open stale;
    stale.rec = *it;
    stale.rec.partial = true;
    stale.partial_reason = "gateway_restart";
    stale.rec.state = storage::RideState::kClosed;
    stale.rec.end_us = it->start_us + from_seconds(it->duration_s).count();
    resume_track(stale.rec, stale.track);
    emit(stale.rec, stale, true);
    ++rides_closed_;
  }

  Open o;
  o.rec = *newest;
  o.rec.state = storage::RideState::kOpen;
  o.rec.end_us.reset();
  o.rec.partial = true;
  o.partial_reason = "gateway_restart";
  resume_track(o.rec, o.track);
  const Micros checkpointed = Micros(o.rec.start_us) + from_seconds(o.rec.duration_s);
  o.attributed_until = checkpointed;
  o.base_distance_km = o.rec.distance_km;
  o.base_integrated_km = o.rec.distance_integrated_km;
  o.latest_soc = o.rec.soc_end_pct ? std::optional<double>(*o.rec.soc_end_pct) : std::nullopt;
  // The odometer seen at the checkpoint seeds the primary counter, so the steps the MC made while
  // the gateway was down are counted by its first reading.
  if (o.rec.end_odo_km && !counters_[0].last) {
    counters_[0].last = *o.rec.end_odo_km;
    counters_[0].at = checkpointed;
    o.valid[0] = true;
  }
  for (std::size_t i = 0; i < counters_.size(); ++i) o.base[i] = counters_[i].total;
  open_ = o;
  at_stop_ = o;
  moving_ = false;
  last_motion_ = checkpointed;
  resumed_at_ = now;
  energy_until_ = now;
  next_checkpoint_ = now;  // persist the partial flag right away
}

void RideTracker::on_message(const motinova::DecodedMessage& msg, Micros now) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return;
  switch (classify(msg)) {
    case BusEvent::kVehicleLock:
      vehicle_locked_ = true;
      if (open_) close(now, false);
      return;
    case BusEvent::kVehicleUnlock:
      vehicle_locked_ = false;
      all_locks_locked_ = false;
      return;
    case BusEvent::kShutdown:
      // Power goes off about a second later; until then the MC still reports the old speed,
      // which must not start a new ride. A shutdown that did not happen ends the hold.
      no_start_until_ = now + config_.shutdown_hold;
      if (open_) close(now, false);
      return;
    case BusEvent::kOther:
      break;
  }
  const motinova::Node src = msg.desc->source();
  const std::string_view name = msg.desc->name;
  if (src == motinova::Node::kMc) last_mc_ = now;
  if (name == "mc_status") {
    on_mc_status(msg, now);
  } else if (name == "mc_odometer") {
    if (const auto odo = msg.number("odo_km")) {
      fine_odo_ = *odo;
      feed_counter(0, *odo, 0.1, now);
    }
    check_counter_start(now);
  } else if (name == "bms_status") {
    on_bms_status(msg, now);
  } else if (name == "lock_status" && motinova::is_lock(src)) {
    on_lock_status(msg, now);
  }
  // A resumed ride waits for the MC (and for the odometer it was seeded with, which tells
  // whether the bike moved while the gateway was down) before the stationary timer may end it.
  if (resumed_at_ && src == motinova::Node::kMc &&
      (!open_ || !open_->valid[0] || name == "mc_odometer")) {
    resumed_at_.reset();
  }
}

void RideTracker::on_fault_raised(Micros) {
  if (open_) ++open_->rec.fault_count;
}

void RideTracker::feed_counter(std::size_t i, double value, double resolution_km, Micros now) {
  Counter& c = counters_[i];
  bool stepped = false;
  if (c.last) {
    const double step = value - *c.last;
    const double limit =
        config_.max_plausible_kmh * seconds(now - c.at) / kHour + 1.5 * resolution_km;
    // Decreases (trip reset by CLEAR, MC replaced) and implausible jumps are not distance.
    if (step > 0 && step <= limit) {
      c.total += step;
      stepped = true;
    }
  }
  c.last = value;
  c.at = now;
  if (!open_) return;
  if (stepped && i == 0 && !moving_) {
    // The bike moved since the previous reading although the MC's speed says it stands: the
    // tail of the last movement, or motion while the gateway was down. The stop moves here.
    attribute(*open_, now);
    last_motion_ = now;
    at_stop_ = open_;
    at_stop_->latest_soc = soc(now);
  }
}

void RideTracker::on_mc_status(const motinova::DecodedMessage& msg, Micros now) {
  const auto speed = msg.number("speed_kmh");
  update(mc_soc_, msg, "soc_pct", now);
  if (const auto trip = msg.number("trip_km")) feed_counter(1, *trip, 0.1, now);
  if (const auto odo = msg.number("odo_km")) {
    coarse_odo_ = Reading{*odo, now};
    feed_counter(2, *odo, 1.0, now);
  }
  if (const auto t = msg.number("trip_time_s")) trip_time_ = *t;

  // Energy from the MC only while the BMS is not heard.
  const auto v = msg.number("voltage_v");
  const auto i = msg.number("current_a");  // MC bus current: discharge positive
  const bool bms_fresh = bms_at_ && now - *bms_at_ <= config_.bms_fresh;
  if (v && i) {
    if (!bms_fresh) integrate_power(mc_pw_at_, mc_pw_, now);
    mc_pw_ = std::pair{*v * *i, *i};
    mc_pw_at_ = now;
  }

  // Book the interval since the previous sample with the previous sample's values.
  if (open_) attribute(*open_, now);
  if (speed) {
    speed_ = *speed;
    speed_at_ = now;
  } else {
    speed_.reset();
  }
  assist_ = assist_name(msg);
  if (const auto raw = msg.raw("assist")) assist_raw_[assist_] = static_cast<unsigned>(*raw);

  if (open_ && speed_) {
    open_->rec.max_speed_kmh = std::max(open_->rec.max_speed_kmh, *speed_);
    if (*speed_ >= config_.standstill_kmh) {
      moving_ = true;
      last_motion_ = now;
    } else if (moving_) {
      moving_ = false;
      last_motion_ = now;
      at_stop_ = open_;
      at_stop_->latest_soc = soc(now);
    }
  }
  if (!open_ && now >= no_start_until_ && !vehicle_locked_ && !all_locks_locked_ && speed_ &&
      *speed_ > config_.moving_speed_kmh) {
    start(now);
  }
  check_counter_start(now);
}

void RideTracker::check_counter_start(Micros now) {
  if (open_) {
    trip_time_base_.reset();
    return;
  }
  // Baselines while parked: renewed regularly so that only a sustained advance starts a ride.
  if (!trip_time_base_ || (trip_time_ && *trip_time_ < trip_time_base_->value) ||
      now - trip_time_base_->at > kTripTimeWindow) {
    if (trip_time_) trip_time_base_ = Reading{*trip_time_, now};
  }
  for (std::size_t i = 0; i < 2; ++i) {
    if (now - parked_base_[i].at > kParkedBaselineAge) {
      parked_base_[i] = Reading{counters_[i].total, now};
    }
  }
  if (vehicle_locked_ || all_locks_locked_ || now < no_start_until_) return;
  bool advanced = trip_time_ && trip_time_base_ &&
                  *trip_time_ - trip_time_base_->value >= config_.counter_start_s;
  for (std::size_t i = 0; i < 2 && !advanced; ++i) {
    // Distance counters: compare with the running totals captured when the bike parked.
    advanced = counters_[i].total - parked_base_[i].value >= kCounterStartKm;
  }
  if (advanced) start(now);
}

void RideTracker::on_bms_status(const motinova::DecodedMessage& msg, Micros now) {
  update(bms_soc_, msg, "soc_pct", now);
  bms_at_ = now;
  const auto v = msg.number("voltage_v");
  const auto i = msg.number("current_a");  // BMS: charge positive (U4 applied by decode())
  if (v && i) {
    const double discharge_a = -*i;
    integrate_power(bms_pw_at_, bms_pw_, now);
    bms_pw_ = std::pair{*v * discharge_a, discharge_a};
    bms_pw_at_ = now;
  }
}

void RideTracker::integrate_power(const std::optional<Micros>& last_at,
                                  const std::optional<std::pair<double, double>>& last,
                                  Micros now) {
  // Sample and hold of the previous reading of this source, from where the last integration of
  // any source stopped (so switching sources never counts an interval twice).
  if (open_ && last && last_at && now - *last_at <= config_.sample_gap) {
    const Micros from = std::max(energy_until_, *last_at);
    if (now > from) {
      const double h = seconds(now - from) / kHour;
      open_->rec.energy_wh += last->first * h;
      open_->rec.energy_mah += last->second * h * 1000.0;
    }
  }
  energy_until_ = std::max(energy_until_, now);
}

void RideTracker::on_lock_status(const motinova::DecodedMessage& msg, Micros now) {
  const auto state = msg.raw("state");
  if (!state) return;
  const auto idx = static_cast<std::size_t>(motinova::lock_index(msg.desc->source()));
  const std::optional<int64_t> before = lock_states_[idx];
  lock_states_[idx] = *state;
  if (!before || *before == *state) return;
  constexpr int64_t kLocked = 2;  // U19
  if (*state != kLocked) {
    all_locks_locked_ = false;
    return;
  }
  const bool all = std::all_of(lock_states_.begin(), lock_states_.end(),
                               [](const auto& s) { return !s || *s == kLocked; });
  if (all) {
    all_locks_locked_ = true;
    if (open_) close(now, false);
  }
}

void RideTracker::start(Micros now) {
  Open o;
  o.rec.ride_id = config_.ride_id_prefix + utc_basic(now);
  o.rec.state = storage::RideState::kOpen;
  o.rec.start_us = now.count();
  o.rec.start_odo_km = odometer();
  o.rec.end_odo_km = o.rec.start_odo_km;
  o.rec.soc_start_pct = whole_percent(soc(now));
  o.latest_soc = soc(now);
  o.attributed_until = now;
  for (std::size_t i = 0; i < counters_.size(); ++i) {
    o.base[i] = counters_[i].total;
    o.valid[i] = counters_[i].last.has_value();
  }
  open_ = std::move(o);
  at_stop_.reset();
  moving_ = true;
  last_motion_ = now;
  energy_until_ = now;
  next_checkpoint_ = now;  // the ride exists on disk from its first moment
  checkpoint(now);
}

void RideTracker::attribute(Open& o, Micros until) const {
  if (until <= o.attributed_until) return;
  Micros covered{0};
  if (speed_ && speed_at_) {
    const Micros covered_end = std::min(until, *speed_at_ + config_.sample_gap);
    covered = std::max(Micros{0}, covered_end - o.attributed_until);
  }
  const Micros uncovered = (until - o.attributed_until) - covered;
  if (covered > Micros{0}) {
    const double s = seconds(covered);
    o.rec.assist_time_s[assist_] += s;
    if (*speed_ >= config_.standstill_kmh) o.rec.moving_s += s;
    o.rec.distance_integrated_km += *speed_ * s / kHour;
  }
  if (uncovered > Micros{0}) o.rec.assist_time_s["unknown"] += seconds(uncovered);
  o.attributed_until = until;
}

std::optional<double> RideTracker::soc(Micros now) const {
  if (const auto v = fresh(bms_soc_, now, kSocFresh)) return v;
  if (const auto v = fresh(mc_soc_, now, kSocFresh)) return v;
  if (bms_soc_) return bms_soc_->value;
  if (mc_soc_) return mc_soc_->value;
  return std::nullopt;
}

std::optional<double> RideTracker::odometer() const {
  if (fine_odo_) return fine_odo_;
  if (coarse_odo_) return coarse_odo_->value;
  return std::nullopt;
}

storage::RideRow RideTracker::snapshot(const Open& o, Micros until) const {
  storage::RideRow rec = o.rec;
  rec.duration_s = seconds(until - Micros(rec.start_us));
  rec.end_odo_km = odometer() ? odometer() : rec.end_odo_km;
  std::optional<double> counted;
  for (std::size_t i = 0; i < counters_.size() && !counted; ++i) {
    if (o.valid[i]) counted = counters_[i].total - o.base[i];
  }
  // Without a counter, the integrated distance since the start (or resume) stands in.
  rec.distance_km =
      o.base_distance_km + counted.value_or(rec.distance_integrated_km - o.base_integrated_km);
  rec.avg_speed_kmh = rec.moving_s > 0 ? rec.distance_integrated_km / (rec.moving_s / kHour) : 0;
  if (!o.track.empty()) {
    // The same start, end, distance and simplified track as the RideRecord payload.
    rec.start_lat_deg = o.track.start()->lat_deg;
    rec.start_lon_deg = o.track.start()->lon_deg;
    rec.end_lat_deg = o.track.end()->lat_deg;
    rec.end_lon_deg = o.track.end()->lon_deg;
    rec.gnss_distance_m = o.track.distance_m();
    std::vector<storage::TrackPoint> points;
    for (const gnss::Fix& p : o.track.simplified()) points.push_back({p.lat_deg, p.lon_deg});
    rec.track = storage::track_text(points);
  }
  return rec;
}

void RideTracker::emit(const storage::RideRow& rec, const Open& o, bool with_payload) {
  storage::PendingRow<storage::RideRow> p{rec, std::nullopt};
  if (with_payload) {
    p.uplink = ride_payload(rec, RideExtras{o.partial_reason, assist_raw_, &o.track});
  }
  sink_.batch().rides.push_back(std::move(p));
}

void RideTracker::checkpoint(Micros now) {
  attribute(*open_, now);
  storage::RideRow rec = snapshot(*open_, now);
  rec.soc_end_pct = whole_percent(soc(now));
  emit(rec, *open_, false);
  next_checkpoint_ = now + config_.checkpoint_interval;
}

void RideTracker::close(Micros end, bool at_stop) {
  Open o = (at_stop && at_stop_) ? *at_stop_ : *open_;
  if (!at_stop) {
    attribute(o, end);
    o.latest_soc = soc(end);
  }
  storage::RideRow rec = snapshot(o, end);
  rec.state = storage::RideState::kClosed;
  rec.end_us = end.count();
  rec.soc_end_pct = whole_percent(o.latest_soc);
  emit(rec, o, true);
  ++rides_closed_;
  open_.reset();
  at_stop_.reset();
  moving_ = false;
  resumed_at_.reset();
  for (std::size_t i = 0; i < 2; ++i) parked_base_[i] = Reading{counters_[i].total, end};
  trip_time_base_.reset();
}

void RideTracker::tick(Micros now) {
  if (!open_) return;
  const Micros mc_ref = last_mc_ ? *last_mc_ : resumed_at_.value_or(now);
  if (now - mc_ref > config_.mc_offline_timeout && !open_->rec.partial) {
    open_->rec.partial = true;
    open_->partial_reason = "bus_lost";
    if (at_stop_) {
      at_stop_->rec.partial = true;
      at_stop_->partial_reason = "bus_lost";
    }
  }
  if (now - mc_ref >= config_.stationary_end) {
    // Nothing from the MC for as long as a parked bike would wait: the ride ended unseen.
    if (moving_) {
      close(std::max(mc_ref, Micros(open_->rec.start_us)), false);
    } else {
      close(last_motion_, true);
    }
    return;
  }
  if (!moving_ && !resumed_at_ && now - last_motion_ >= config_.stationary_end) {
    close(last_motion_, true);
    return;
  }
  if (now >= next_checkpoint_) checkpoint(now);
}

std::optional<storage::RideRow> RideTracker::current(Micros now) const {
  if (!open_) return std::nullopt;
  Open o = *open_;
  attribute(o, now);
  storage::RideRow rec = snapshot(o, now);
  rec.soc_end_pct = whole_percent(soc(now));
  return rec;
}

}  // namespace fleetgw::domain
