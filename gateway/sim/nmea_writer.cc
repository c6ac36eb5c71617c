#include "gateway/sim/nmea_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace fleetgw::sim {
namespace {

std::string errno_text(const std::string& what) {
  return what + ": " + std::strerror(errno);
}

// Civil date of a day count since 1970-01-01 (H. Hinnant's algorithm).
void civil_from_days(int64_t z, int& y, unsigned& m, unsigned& d) {
  z += 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const unsigned doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  d = doy - (153 * mp + 2) / 5 + 1;
  m = mp < 10 ? mp + 3 : mp - 9;
  y = static_cast<int>(static_cast<int64_t>(yoe) + era * 400 + (m <= 2));
}

}  // namespace

std::string nmea_checksum(std::string_view body) {
  unsigned x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char out[3];
  std::snprintf(out, sizeof out, "%02X", x & 0xFFu);
  return out;
}

std::string nmea_sentence(std::string_view body) {
  return "$" + std::string(body) + "*" + nmea_checksum(body) + "\r\n";
}

std::string nmea_angle(double deg, bool latitude) {
  const char hemi = latitude ? (deg < 0 ? 'S' : 'N') : (deg < 0 ? 'W' : 'E');
  // Rounded once, in units of 1e-5 minute: the carry goes into the degrees, so a value just
  // below a whole degree prints as that degree and 0 minutes instead of "60.00000".
  const auto units = static_cast<int64_t>(std::llround(std::fabs(deg) * 60.0 * 1e5));
  const int64_t per_degree = 60 * 100'000;
  const auto whole = static_cast<int>(units / per_degree);
  const int64_t rest = units % per_degree;
  char out[32];
  std::snprintf(out, sizeof out, latitude ? "%02d%02d.%05d,%c" : "%03d%02d.%05d,%c", whole,
                static_cast<int>(rest / 100'000), static_cast<int>(rest % 100'000), hemi);
  return out;
}

std::string nmea_fix(const NmeaFix& fix) {
  // Hundredths of a second: the simulator samples between whole seconds of bus time.
  const int64_t centis = fix.utc.count() / 10'000;
  const int64_t days = centis / 8'640'000;
  const int64_t of_day = centis % 8'640'000;
  int year = 0;
  unsigned month = 0, day = 0;
  civil_from_days(days, year, month, day);
  char hms[48];
  std::snprintf(hms, sizeof hms, "%02d%02d%02d.%02d", static_cast<int>(of_day / 360'000),
                static_cast<int>(of_day / 6000 % 60), static_cast<int>(of_day / 100 % 60),
                static_cast<int>(of_day % 100));
  char date[32];
  std::snprintf(date, sizeof date, "%02u%02u%02d", day, month, year % 100);
  const std::string lat = nmea_angle(fix.position.lat_deg, true);
  const std::string lon = nmea_angle(fix.position.lon_deg, false);
  char gga_tail[64];
  std::snprintf(gga_tail, sizeof gga_tail, ",1,%02d,%.1f,%.1f,M,45.0,M,,", fix.satellites, fix.hdop,
                fix.altitude_m);
  // RMC: speed over ground in knots and course, then the date (no magnetic variation).
  char speed[32];
  std::snprintf(speed, sizeof speed, "%.1f,%.1f", fix.speed_kmh / 1.852, fix.course_deg);
  std::string out = nmea_sentence("GPGGA," + std::string(hms) + "," + lat + "," + lon + gga_tail);
  out += nmea_sentence("GPRMC," + std::string(hms) + ",A," + lat + "," + lon + "," + speed + "," +
                       date + ",,,A");
  return out;
}

NmeaPty::NmeaPty(std::filesystem::path link) : link_(std::move(link)) {
  master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (master_ < 0) throw std::runtime_error(errno_text("sim.nmea_pty: posix_openpt"));
  if (::grantpt(master_) != 0 || ::unlockpt(master_) != 0) {
    const std::string why = errno_text("sim.nmea_pty: grantpt/unlockpt");
    ::close(master_);
    throw std::runtime_error(why);
  }
  char name[128];
  if (::ptsname_r(master_, name, sizeof name) != 0) {
    const std::string why = errno_text("sim.nmea_pty: ptsname");
    ::close(master_);
    throw std::runtime_error(why);
  }
  slave_path_ = name;
  // Held open by us: the pty stays usable across gpsd restarts, and raw mode (no echo, no
  // line editing) is set before any reader comes.
  slave_ = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (slave_ < 0) {
    const std::string why = errno_text("sim.nmea_pty: open " + slave_path_);
    ::close(master_);
    throw std::runtime_error(why);
  }
  termios tio{};
  if (::tcgetattr(slave_, &tio) == 0) {
    ::cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    ::cfsetispeed(&tio, B9600);
    ::cfsetospeed(&tio, B9600);
    ::tcsetattr(slave_, TCSANOW, &tio);
  }
  // gpsd drops root privileges before opening its devices: the simulated receiver must be
  // openable by its unprivileged user, like a serial port in the dialout group.
  ::fchmod(slave_, 0666);
  std::error_code ec;
  if (std::filesystem::is_symlink(link_, ec)) std::filesystem::remove(link_, ec);
  std::filesystem::create_symlink(slave_path_, link_, ec);
  if (ec) {
    ::close(slave_);
    ::close(master_);
    throw std::runtime_error("sim.nmea_pty: cannot create symlink " + link_.string() + " -> " +
                             slave_path_ + ": " + ec.message());
  }
}

NmeaPty::~NmeaPty() {
  std::error_code ec;
  if (std::filesystem::read_symlink(link_, ec) == slave_path_ && !ec) {
    std::filesystem::remove(link_, ec);
  }
  if (slave_ >= 0) ::close(slave_);
  if (master_ >= 0) ::close(master_);
}

bool NmeaPty::write(std::string_view text) {
  ::tcflush(master_, TCIFLUSH);  // whatever a reader wrote to the "receiver"
  const ssize_t n = ::write(master_, text.data(), text.size());
  return n == static_cast<ssize_t>(text.size());
}

}  // namespace fleetgw::sim
