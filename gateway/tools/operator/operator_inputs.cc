#include "gateway/tools/operator/operator_inputs.h"

#include <fstream>
#include <iterator>

#include "gateway/uplink/mqtt_connection.h"

namespace fleetgw::tools {

std::optional<std::string> read_file_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  return bytes;
}

std::optional<std::string> broker_option_error(const std::string& broker,
                                               const std::string& username,
                                               const std::string& password,
                                               bool allow_plaintext_credentials) {
  if (broker.rfind("tcp://", 0) != 0 && broker.rfind("ssl://", 0) != 0) {
    return "--broker: tcp://host:port or ssl://host:port";
  }
  if (broker.find('@') != std::string::npos) {
    return "--broker: no credentials in the URI; use --username/--password";
  }
  if (!uplink::uses_tls(broker) && (!username.empty() || !password.empty()) &&
      !allow_plaintext_credentials) {
    return "refusing to send credentials over plain tcp://; use ssl://";
  }
  return std::nullopt;
}

}  // namespace fleetgw::tools
