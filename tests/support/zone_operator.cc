#include "tests/support/zone_operator.h"

#include <fstream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "tests/support/process.h"

namespace fleetgw::testing {

std::string geojson_rect(double lon0, double lon1, double lat0, double lat1) {
  std::ostringstream o;
  o.precision(9);
  o << "[[[" << lon0 << "," << lat0 << "],[" << lon1 << "," << lat0 << "],[" << lon1 << "," << lat1
    << "],[" << lon0 << "," << lat1 << "]]]";
  return o.str();
}

std::string geojson_feature(const std::string& id, const std::string& kind,
                            const std::string& coordinates, const std::string& extra) {
  return R"({"type": "Feature", "properties": {"id": ")" + id + R"(", "kind": ")" + kind + "\"" +
         extra + R"(}, "geometry": {"type": "Polygon", "coordinates": )" + coordinates + "}}";
}

ZoneOperator::ZoneOperator(const TempDir& dir, std::filesystem::path binary)
    : dir_(dir.path()), binary_(std::move(binary)) {
  const std::string keygen = run({"keygen", (dir_ / "ops").string()});
  const auto from = keygen.find("ops = \"");
  if (from == std::string::npos) {
    throw std::runtime_error("fleetgw keygen printed no `ops = \"...\"` line:\n" + keygen);
  }
  key_line_ = keygen.substr(from, keygen.find('\n', from) - from);
}

std::filesystem::path ZoneOperator::bundle_file(int version,
                                                const std::vector<std::string>& features) const {
  std::string all;
  for (const auto& f : features) all += (all.empty() ? "" : ",") + f;
  const auto geojson = dir_ / ("zones-" + std::to_string(version) + ".geojson");
  const auto out = dir_ / ("zones-" + std::to_string(version) + ".pb");
  std::ofstream(geojson) << R"({"type": "FeatureCollection", "features": [)" << all << "]}";
  run({"zones", "sign", geojson.string(), "--version", std::to_string(version), "--key",
       key_file().string(), "--out", out.string()});
  if (!std::filesystem::exists(out)) {
    throw std::runtime_error("fleetgw zones sign exited 0 but wrote no " + out.string());
  }
  return out;
}

std::string ZoneOperator::bundle(int version, const std::vector<std::string>& features) const {
  return read_text_file(bundle_file(version, features));
}

std::string ZoneOperator::run(const std::vector<std::string>& args) const {
  std::vector<std::string> argv{binary_.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto out = dir_ / "tool.out";
  std::filesystem::remove(out);
  run_program(argv, out);  // throws with the output when the tool fails
  return read_text_file(out);
}

}  // namespace fleetgw::testing
