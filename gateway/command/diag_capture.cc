// The lifetime records as last seen on the bus (issue 29); see diag_capture.h.
#include "gateway/command/diag_capture.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <charconv>

#include "motinova/catalogue.h"
#include "storage/store.h"

namespace fleetgw::command {
namespace {

constexpr std::string_view kKeyPrefix = "diag.captured.";
// The records kept: (catalogue name, CAN ID, function).
struct CapturedKind {
  std::string_view name;
  std::uint16_t can_id;
  std::uint8_t function;
};
constexpr CapturedKind kCaptured[] = {
    {"mc_lifetime_1", 0x715, 0xA2},
    {"mc_lifetime_2", 0x715, 0xAC},
    {"pack_stats", 0x725, 0x50},
};

const CapturedKind* captured_kind_of(const motinova::AppFrame& f) {
  for (const auto& k : kCaptured) {
    if (k.can_id == f.can_id && k.function == f.function) return &k;
  }
  return nullptr;
}

std::string to_hex_text(std::span<const std::uint8_t> bytes) {
  std::string out;
  for (const auto b : bytes) out += fmt::format("{:02x}", b);
  return out;
}

std::optional<std::vector<std::uint8_t>> from_hex_text(std::string_view text) {
  if (text.size() % 2 != 0) return std::nullopt;
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i < text.size(); i += 2) {
    unsigned v = 0;
    const auto [end, ec] = std::from_chars(text.data() + i, text.data() + i + 2, v, 16);
    if (ec != std::errc() || end != text.data() + i + 2) return std::nullopt;
    out.push_back(static_cast<std::uint8_t>(v));
  }
  return out;
}

}  // namespace

DiagCapture::DiagCapture(storage::Store& store, Micros persist_interval)
    : store_(store), persist_interval_(persist_interval) {
  for (const auto& k : kCaptured) {
    Slot& slot = slots_[std::string(k.name)];
    try {
      const auto text = store_.meta(std::string(kKeyPrefix) + std::string(k.name));
      if (!text) continue;
      const auto space = text->find(' ');
      std::int64_t at = 0;
      const auto [end, ec] = std::from_chars(text->data(), text->data() + space, at);
      const auto data = space == std::string::npos
                            ? std::nullopt
                            : from_hex_text(std::string_view(*text).substr(space + 1));
      const auto* desc = motinova::Catalogue::standard().find(k.can_id, k.function);
      if (ec != std::errc() || end != text->data() + space || !data || desc == nullptr ||
          data->size() != desc->length) {
        spdlog::error("diagnostics: stored {} record is damaged; ignored", k.name);
        continue;
      }
      motinova::AppFrame f;
      f.can_id = k.can_id;
      f.function = k.function;
      f.mode = motinova::Mode::kReport;
      f.data.assign(*data);
      slot.record = Record{f, at};
    } catch (const std::exception& e) {
      spdlog::error("diagnostics: reading the stored {} record failed: {}", k.name, e.what());
    }
  }
}

void DiagCapture::on_message(const motinova::DecodedMessage& msg, std::int64_t wall_us) {
  if (msg.frame == nullptr || msg.status != motinova::DecodeStatus::kOk) return;
  const auto* k = captured_kind_of(*msg.frame);
  if (k == nullptr) return;
  Slot& slot = slots_[std::string(k->name)];
  const bool changed = !slot.record || !(slot.record->frame == *msg.frame);
  slot.record = Record{*msg.frame, wall_us};
  // Written at the next tick, not from the frame handler.
  if (changed) slot.dirty = true;
}

void DiagCapture::tick(Micros now) {
  for (auto& [name, slot] : slots_) {
    if (slot.dirty && (!slot.written || now - *slot.written >= persist_interval_)) {
      persist(name, slot, now);
    }
  }
}

std::optional<Micros> DiagCapture::next_due() const {
  std::optional<Micros> due;
  for (const auto& [name, slot] : slots_) {
    if (!slot.dirty) continue;
    const Micros at = slot.written ? *slot.written + persist_interval_ : Micros{0};
    if (!due || at < *due) due = at;
  }
  return due;
}

void DiagCapture::persist(const std::string& name, Slot& slot, Micros now) {
  storage::Batch b;
  b.now_us = now.count();
  b.meta.emplace_back(std::string(kKeyPrefix) + name,
                      fmt::format("{} {}", slot.record->heard_wall_us,
                                  to_hex_text(slot.record->frame.data.span())));
  // Store::write never throws: a disk error comes back in the result.
  const auto written = store_.write(b);
  if (!written.ok()) {
    spdlog::error("diagnostics: storing the {} record failed: {}", name,
                  written.status().message);
    slot.written = now;  // tried again after the interval, not on every frame
    return;
  }
  slot.dirty = false;
  slot.written = now;
}

const DiagCapture::Record* DiagCapture::latest(std::string_view message) const {
  const auto it = slots_.find(message);
  return it == slots_.end() || !it->second.record ? nullptr : &*it->second.record;
}

std::vector<std::string> DiagCapture::captured() const {
  std::vector<std::string> out;
  for (const auto& [name, slot] : slots_) {
    if (slot.record) out.push_back(name);
  }
  return out;
}

}  // namespace fleetgw::command
