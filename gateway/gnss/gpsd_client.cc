#include "gateway/gnss/gpsd_client.h"

#include <gps.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace fleetgw::gnss {

struct GpsdClient::Data {
  gps_data_t gps{};
};

void GpsdClient::DataDeleter::operator()(Data* d) const {
  gps_stream(&d->gps, WATCH_DISABLE, nullptr);
  gps_close(&d->gps);
  std::default_delete<Data>()(d);
}

GpsdClient::GpsdClient(std::string host, std::string port)
    : host_(std::move(host)), port_(std::move(port)) {}

GpsdClient::~GpsdClient() = default;

std::string GpsdClient::connect() {
  close();
  auto data = std::make_unique<Data>();
  errno = 0;
  if (gps_open(host_.c_str(), port_.c_str(), &data->gps) != 0) {
    const int err = errno;
    return "connect to " + endpoint() + ": " + gps_errstr(err);
  }
  // From here on gps_close() must run: hand the connection to the deleter first.
  data_.reset(data.release());
  if (gps_stream(&data_->gps, WATCH_ENABLE | WATCH_JSON, nullptr) != 0) {
    close();
    return "watch request to " + endpoint() + " failed";
  }
  return {};
}

void GpsdClient::close() {
  data_.reset();
}

int GpsdClient::fd() const {
  return data_ ? static_cast<int>(data_->gps.gps_fd) : -1;
}

namespace {

bool plausible(double lat, double lon) {
  return std::isfinite(lat) && std::isfinite(lon) && std::fabs(lat) <= 90.0 &&
         std::fabs(lon) <= 180.0;
}

}  // namespace

GpsdClient::ReadStatus GpsdClient::read_available(Micros now, std::vector<GnssReport>& out) {
  if (!data_) return ReadStatus::kClosed;
  gps_data_t& g = data_->gps;
  // gps_waiting(…, 0) does not block: buffered bytes or a readable socket.
  while (gps_waiting(&g, 0)) {
    g.set = 0;
    if (gps_read(&g, nullptr, 0) < 0) {
      close();
      return ReadStatus::kClosed;
    }
    if ((g.set & DOP_SET) && std::isfinite(g.dop.hdop) && g.dop.hdop >= 0) hdop_ = g.dop.hdop;
    if (g.set & SATELLITE_SET) satellites_ = std::max(0, g.satellites_used);
    if (!(g.set & MODE_SET)) continue;  // not a TPV report
    GnssReport report;
    if (g.fix.mode >= MODE_2D && (g.set & LATLON_SET) &&
        plausible(g.fix.latitude, g.fix.longitude)) {
      Position p;
      p.lat_deg = g.fix.latitude;
      p.lon_deg = g.fix.longitude;
      p.three_d = g.fix.mode >= MODE_3D;
      if (p.three_d && std::isfinite(g.fix.altMSL)) p.alt_m = g.fix.altMSL;
      p.hdop = hdop_;
      p.satellites = satellites_;
      if (g.set & TIME_SET) {
        p.fixed_at =
            Micros(static_cast<int64_t>(g.fix.time.tv_sec) * 1'000'000 + g.fix.time.tv_nsec / 1000);
      }
      p.received_at = now;
      report.fix = p;
    }
    out.push_back(report);
  }
  return ReadStatus::kOk;
}

}  // namespace fleetgw::gnss
