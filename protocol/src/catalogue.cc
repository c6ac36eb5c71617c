// Catalogue construction, validation and look-up, plus the shared table builders.

#include "motinova/catalogue.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "catalogue_tables.h"

namespace motinova {
namespace {

uint32_t key_of(uint16_t can_id, uint8_t function, uint8_t length) {
  return (static_cast<uint32_t>(can_id) << 16) | (static_cast<uint32_t>(function) << 8) | length;
}

std::string describe(const MessageDesc& m) {
  char buf[48];
  std::snprintf(buf, sizeof buf, " (0x%03X/0x%04X)", static_cast<unsigned>(m.can_id),
                static_cast<unsigned>(m.command()));
  return std::string(m.name) + buf;
}

// A malformed table is a programming error: reject it loudly at construction time rather than
// decoding garbage later.
void validate(const MessageDesc& m) {
  auto fail = [&](const std::string& what) {
    throw std::invalid_argument("motinova catalogue: message " + describe(m) + ": " + what);
  };
  if (m.name.empty()) fail("empty name");
  if (m.kind == MessageKind::kKeyword && m.keyword.size() != m.length) {
    fail("keyword \"" + std::string(m.keyword) + "\" does not fill the declared length");
  }
  for (const FieldDesc& f : m.fields) {
    if (f.name.empty()) fail("field with empty name");
    const unsigned count = f.kind == FieldKind::kArray ? f.count : 1;
    if (f.size == 0 || count == 0) fail("field '" + std::string(f.name) + "' has no bytes");
    if (f.offset + f.size * count > m.length) {
      fail("field '" + std::string(f.name) + "' ends beyond DATA");
    }
    const bool integer = f.kind == FieldKind::kUnsigned || f.kind == FieldKind::kSigned ||
                         f.kind == FieldKind::kBool || f.kind == FieldKind::kEnum ||
                         f.kind == FieldKind::kFlags;
    if (integer && f.size > 4) fail("integer field '" + std::string(f.name) + "' wider than 4");
    if (f.kind == FieldKind::kFaultWord && f.size != 4) {
      fail("fault word '" + std::string(f.name) + "' is not 4 bytes");
    }
    if (f.scale == 0.0) fail("field '" + std::string(f.name) + "' has scale 0");
  }
}

}  // namespace

Catalogue::Catalogue(std::vector<MessageDesc> messages) : messages_(std::move(messages)) {
  index_.reserve(messages_.size());
  for (std::size_t i = 0; i < messages_.size(); ++i) {
    validate(messages_[i]);
    index_.emplace_back(key_of(messages_[i].can_id, messages_[i].function, messages_[i].length),
                        static_cast<uint32_t>(i));
  }
  std::sort(index_.begin(), index_.end());
  const auto dup = std::adjacent_find(index_.begin(), index_.end(),
                                      [](auto& a, auto& b) { return a.first == b.first; });
  if (dup != index_.end()) {
    throw std::invalid_argument("motinova catalogue: " + describe(messages_[dup->second]) +
                                " and " + describe(messages_[(dup + 1)->second]) +
                                " share CAN ID, function code and length");
  }
}

const MessageDesc* Catalogue::find(uint16_t can_id, uint8_t function, uint8_t length) const {
  const uint32_t key = key_of(can_id, function, length);
  const auto it = std::lower_bound(index_.begin(), index_.end(), key,
                                   [](const auto& entry, uint32_t k) { return entry.first < k; });
  if (it == index_.end() || it->first != key) return nullptr;
  return &messages_[it->second];
}

const MessageDesc* Catalogue::find(uint16_t can_id, uint8_t function) const {
  // Lengths sort within one (ID, function) group, so the group starts at length 0.
  const uint32_t key = key_of(can_id, function, 0);
  const auto it = std::lower_bound(index_.begin(), index_.end(), key,
                                   [](const auto& entry, uint32_t k) { return entry.first < k; });
  if (it == index_.end() || (it->first >> 8) != (key >> 8)) return nullptr;
  return &messages_[it->second];
}

const MessageDesc* Catalogue::find(std::string_view name, uint16_t can_id) const {
  for (const MessageDesc& m : messages_) {
    if (m.can_id == can_id && m.name == name) return &m;
  }
  return nullptr;
}

const Catalogue& Catalogue::standard() {
  // Built once on first use (thread-safe function-local static); immutable afterwards.
  static const Catalogue catalogue = [] {
    std::vector<MessageDesc> all;
    all.reserve(320);
    detail::append_mc_messages(all);
    detail::append_bms_messages(all);
    detail::append_obc_iot_messages(all);
    detail::append_lock_messages(all);
    detail::append_v30_messages(all);
    return Catalogue(std::move(all));
  }();
  return catalogue;
}

namespace detail {

std::span<const FieldDesc> keyword_fields(std::size_t length) {
  switch (length) {
    case 3:
      return kKeywordFields<3>;
    case 4:
      return kKeywordFields<4>;
    case 5:
      return kKeywordFields<5>;
    case 6:
      return kKeywordFields<6>;
    case 8:
      return kKeywordFields<8>;
    case 9:
      return kKeywordFields<9>;
    default:
      throw std::invalid_argument("motinova catalogue: no keyword field of length " +
                                  std::to_string(length));
  }
}

MessageDesc keyword_message(std::string_view name, uint16_t can_id, uint8_t function, Mode mode,
                            std::string_view keyword, std::string_view title, SpecVersion version) {
  return {.name = name,
          .can_id = can_id,
          .function = function,
          .length = static_cast<uint8_t>(keyword.size()),
          .mode = mode,
          .kind = MessageKind::kKeyword,
          .fields = keyword_fields(keyword.size()),
          .keyword = keyword,
          .version = version,
          .title = title};
}

MessageDesc read_request(std::string_view name, uint16_t can_id, uint8_t function,
                         std::string_view title, SpecVersion version) {
  return {.name = name,
          .can_id = can_id,
          .function = function,
          .length = 0,
          .mode = Mode::kRead,
          .version = version,
          .title = title};
}

MessageDesc model_info(uint16_t can_id, uint8_t function, std::string_view title,
                       SpecVersion version) {
  return {.name = "device_info",
          .can_id = can_id,
          .function = function,
          .length = 64,
          .mode = Mode::kReport,
          .kind = MessageKind::kModelInfo,
          .fields = kModelInfoFields,
          .version = version,
          .title = title};
}

MessageDesc fault_word(std::string_view name, uint16_t can_id, uint8_t function, FaultSource source,
                       std::string_view title, SpecVersion version) {
  return {.name = name,
          .can_id = can_id,
          .function = function,
          .length = 4,
          .mode = Mode::kReport,
          .kind = MessageKind::kFaultWord,
          .fields = kFaultWordFields,
          .fault_source = source,
          .version = version,
          .title = title};
}

}  // namespace detail
}  // namespace motinova
