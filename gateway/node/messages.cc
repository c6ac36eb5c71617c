#include "gateway/node/messages.h"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

#include "motinova/codec.h"

namespace fleetgw::node {
namespace {

constexpr std::size_t kModelFieldSize = 16;

bool printable_ascii(std::string_view s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c <= 0x7E; });
}

}  // namespace

bool is_keyword(const motinova::AppFrame& frame, std::string_view keyword) {
  const auto data = frame.data.span();
  return data.size() == keyword.size() &&
         std::equal(data.begin(), data.end(), keyword.begin(),
                    [](uint8_t b, char c) { return b == static_cast<uint8_t>(c); });
}

std::optional<uint8_t> lock_state_of(const motinova::AppFrame& frame, int k) {
  if (frame.can_id != ids::lock_broadcast_id(k) || frame.function != fn::kLockStatus ||
      frame.data.size() != kLockStatusLength) {
    return std::nullopt;
  }
  return frame.data[kLockStateOffset];
}

motinova::AppFrame read_request(uint16_t can_id, uint8_t function) {
  return motinova::make_frame(can_id, motinova::Mode::kRead, function, std::span<const uint8_t>{});
}

motinova::AppFrame keyword_frame(uint16_t can_id, motinova::Mode mode, uint8_t function,
                                 std::string_view keyword) {
  return motinova::make_frame(can_id, mode, function, keyword);
}

motinova::AppFrame model_info_frame(std::string_view model, std::string_view serial,
                                    std::string_view hw, std::string_view fw) {
  std::array<uint8_t, 4 * kModelFieldSize> data;
  data.fill(0x20);  // §3.0: ASCII fields are padded with spaces
  const std::array<std::pair<std::string_view, std::string_view>, 4> fields{
      {{"model", model}, {"serial", serial}, {"hw", hw}, {"fw", fw}}};
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const auto& [name, text] = fields[i];
    if (text.size() > kModelFieldSize || !printable_ascii(text)) {
      throw std::invalid_argument("IOT model info: field '" + std::string(name) + "' (\"" +
                                  std::string(text) +
                                  "\") must be at most 16 printable ASCII characters");
    }
    std::copy(text.begin(), text.end(), data.begin() + static_cast<std::ptrdiff_t>(i * 16));
  }
  return motinova::make_frame(ids::kIotBroadcast, motinova::Mode::kReport, fn::kIotModelInfo, data);
}

motinova::AppFrame fault_word_frame(uint32_t normalised, const motinova::DecodeOptions& options) {
  std::array<uint8_t, 4> wire{};
  motinova::write_fault_word(normalised, options.data_order,
                             motinova::fault_layout_for(motinova::FaultSource::kIot, options),
                             wire);
  return motinova::make_frame(ids::kIotBroadcast, motinova::Mode::kReport, fn::kIotFaults, wire);
}

std::string format_firmware(std::string_view version, std::string_view yyyymmdd) {
  const bool date_ok =
      yyyymmdd.size() == 8 &&
      std::all_of(yyyymmdd.begin(), yyyymmdd.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (!date_ok) {
    throw std::invalid_argument("firmware date \"" + std::string(yyyymmdd) + "\" is not YYYYMMDD");
  }
  std::string fw = "V" + std::string(version) + "_" + std::string(yyyymmdd);
  if (fw.size() > kModelFieldSize || !printable_ascii(version) || version.empty()) {
    throw std::invalid_argument("firmware string \"" + fw +
                                "\" does not fit the 16-byte FW field (Vx.x.x_YYYYMMDD)");
  }
  return fw;
}

}  // namespace fleetgw::node
