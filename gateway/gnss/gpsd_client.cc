#include "gateway/gnss/gpsd_client.h"

#include <dlfcn.h>
#include <gps.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace fleetgw::gnss {

// libgps, loaded when the first client connects. Linked normally, it would bring libdbus,
// libsystemd, libgcrypt and five more libraries into every fleetgw process, ~1.4 MB resident,
// although [gnss] is off by default. The header (gps_data_t, the WATCH_ flags) is the one of
// the library whose soname the build recorded (FLEETGW_LIBGPS_SONAME), so the layouts agree.
struct GpsdClient::Library {
  void* handle = nullptr;
  decltype(&::gps_open) open = nullptr;
  decltype(&::gps_close) close = nullptr;
  decltype(&::gps_stream) stream = nullptr;
  decltype(&::gps_waiting) waiting = nullptr;
  decltype(&::gps_read) read = nullptr;
  decltype(&::gps_errstr) errstr = nullptr;

  Library() = default;
  Library(const Library&) = delete;  // one dlclose() per dlopen()
  Library& operator=(const Library&) = delete;
  ~Library() {
    if (handle != nullptr) dlclose(handle);
  }
};

namespace {

template <typename F>
bool resolve(void* handle, const char* name, F& out) {
  out = reinterpret_cast<F>(dlsym(handle, name));
  return out != nullptr;
}

}  // namespace

std::string GpsdClient::load_library() {
  if (library_) return {};
  auto lib = std::make_unique<Library>();
  // NODELETE: a dlclose() never unmaps code that libgps's dependencies may still run at exit.
  lib->handle = dlopen(library_name_.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
  if (lib->handle == nullptr) {
    const char* why = dlerror();
    return "cannot load " + library_name_ +
           ", needed for [gnss]: " + (why != nullptr ? why : "unknown error");
  }
  const char* missing = nullptr;
  if (!resolve(lib->handle, "gps_open", lib->open)) missing = "gps_open";
  if (!resolve(lib->handle, "gps_close", lib->close)) missing = "gps_close";
  if (!resolve(lib->handle, "gps_stream", lib->stream)) missing = "gps_stream";
  if (!resolve(lib->handle, "gps_waiting", lib->waiting)) missing = "gps_waiting";
  if (!resolve(lib->handle, "gps_read", lib->read)) missing = "gps_read";
  if (!resolve(lib->handle, "gps_errstr", lib->errstr)) missing = "gps_errstr";
  if (missing != nullptr) return library_name_ + " has no " + missing;
  library_ = std::move(lib);
  return {};
}

struct GpsdClient::Data {
  gps_data_t gps{};
  const Library* library = nullptr;
};

void GpsdClient::DataDeleter::operator()(Data* d) const {
  d->library->stream(&d->gps, WATCH_DISABLE, nullptr);
  d->library->close(&d->gps);
  std::default_delete<Data>()(d);
}

GpsdClient::GpsdClient(std::string host, std::string port, std::string library_name)
    : host_(std::move(host)), port_(std::move(port)), library_name_(std::move(library_name)) {}

GpsdClient::~GpsdClient() {
  close();  // before the library it calls into
}

std::string GpsdClient::connect() {
  close();
  if (auto error = load_library(); !error.empty()) return error;
  auto data = std::make_unique<Data>();
  data->library = library_.get();
  errno = 0;
  if (library_->open(host_.c_str(), port_.c_str(), &data->gps) != 0) {
    const int err = errno;
    return "connect to " + endpoint() + ": " + library_->errstr(err);
  }
  // From here on gps_close() must run: hand the connection to the deleter first.
  data_.reset(data.release());
  if (library_->stream(&data_->gps, WATCH_ENABLE | WATCH_JSON, nullptr) != 0) {
    close();
    return "watch request to " + endpoint() + " failed";
  }
  return {};
}

void GpsdClient::close() {
  data_.reset();
  horizontal_error_m_.reset();
  heading_deg_.reset();
}

int GpsdClient::fd() const {
  return data_ ? static_cast<int>(data_->gps.gps_fd) : -1;
}

namespace {

bool plausible(double lat, double lon) {
  return std::isfinite(lat) && std::isfinite(lon) && std::fabs(lat) <= 90.0 &&
         std::fabs(lon) <= 180.0;
}

// How long a TPV's horizontal error stands for the TPVs after it that carry none.
constexpr Micros kHorizontalErrorMaxAge = std::chrono::seconds(2);

// A TPV's horizontal error in metres: gpsd's eph, else the hypotenuse of its per-axis estimates
// (epx, epy: both needed). Untrusted: negative or non-finite values, or more than the Earth's
// circumference, count as "not reported".
std::optional<double> horizontal_error_m(const gps_fix_t& fix) {
  constexpr double kMaxM = 40'075'000.0;
  auto usable = [](double m) { return std::isfinite(m) && m >= 0 && m <= kMaxM; };
  if (usable(fix.eph)) return fix.eph;
  if (usable(fix.epx) && usable(fix.epy)) {
    const double m = std::hypot(fix.epx, fix.epy);
    if (usable(m)) return m;
  }
  return std::nullopt;
}

// A TPV's course over ground (track), when gpsd reported one with a speed of at least 1 km/h:
// a receiver's course at a standstill is noise. Untrusted: non-finite or out of [0, 360] is none.
std::optional<double> heading_deg(const gps_data_t& g) {
  constexpr double kMinSpeedMps = 1.0 / 3.6;
  if (!(g.set & TRACK_SET) || !(g.set & SPEED_SET)) return std::nullopt;
  const double track = g.fix.track, speed = g.fix.speed;
  if (!std::isfinite(track) || track < 0 || track > 360 || !std::isfinite(speed) ||
      speed < kMinSpeedMps) {
    return std::nullopt;
  }
  return track >= 360 ? 0.0 : track;
}

}  // namespace

GpsdClient::ReadStatus GpsdClient::read_available(Micros now, std::vector<GnssReport>& out) {
  if (!data_) return ReadStatus::kClosed;
  gps_data_t& g = data_->gps;
  // gps_waiting(…, 0) does not block: buffered bytes or a readable socket.
  while (library_->waiting(&g, 0)) {
    g.set = 0;
    if (library_->read(&g, nullptr, 0) < 0) {
      close();
      return ReadStatus::kClosed;
    }
    if ((g.set & DOP_SET) && std::isfinite(g.dop.hdop) && g.dop.hdop >= 0) hdop_ = g.dop.hdop;
    if (g.set & SATELLITE_SET) satellites_ = std::max(0, g.satellites_used);
    if (!(g.set & MODE_SET)) continue;  // not a TPV report
    GnssReport report;
    if (g.fix.mode >= MODE_2D && (g.set & LATLON_SET) &&
        plausible(g.fix.latitude, g.fix.longitude)) {
      Fix p;
      p.lat_deg = g.fix.latitude;
      p.lon_deg = g.fix.longitude;
      p.three_d = g.fix.mode >= MODE_3D;
      if (p.three_d && std::isfinite(g.fix.altMSL)) p.alt_m = g.fix.altMSL;
      p.hdop = hdop_;
      p.satellites = satellites_;
      // gpsd puts eph in some of a cycle's TPV reports only (the GGA's, not the RMC's): a
      // report without one takes the latest one, if gpsd sent it within the last 2 s.
      if (const auto error = horizontal_error_m(g.fix)) {
        horizontal_error_m_ = error;
        horizontal_error_at_ = now;
      } else if (horizontal_error_m_ && now - horizontal_error_at_ > kHorizontalErrorMaxAge) {
        horizontal_error_m_.reset();
      }
      p.horizontal_error_m = horizontal_error_m_;
      // The track comes with the RMC's TPV only: the GGA's takes the latest within 2 s, and a
      // TPV saying the bike stands still clears it.
      if (const auto heading = heading_deg(g)) {
        heading_deg_ = heading;
        heading_at_ = now;
      } else if (((g.set & SPEED_SET) && std::isfinite(g.fix.speed)) ||
                 (heading_deg_ && now - heading_at_ > kHorizontalErrorMaxAge)) {
        heading_deg_.reset();
      }
      p.heading_deg = heading_deg_;
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
