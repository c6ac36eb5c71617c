// Helpers of the campaign tests: a valid campaign to vary, and a bus of decoded MOTINOVA
// messages built with the protocol library's own writer (what the gateway decodes).
#pragma once

#include <deque>
#include <string>
#include <vector>

#include "fleetgw/v1/campaign.pb.h"
#include "gateway/campaign/campaign_engine.h"
#include "gateway/campaign/campaign_spec.h"
#include "motinova/codec.h"

namespace fleetgw::campaign::test {

// 2026-11-29T00:00:00Z in microseconds.
inline constexpr motinova::Micros kDay0{1'795'910'400'000'000};
inline constexpr motinova::Micros kSecond{1'000'000};
inline constexpr motinova::Micros kMs{1'000};

// A campaign every rule accepts: one signal every second, always, for ten days from kDay0.
inline v1::Campaign base_campaign() {
  v1::Campaign c;
  c.set_id("cells-hot");
  c.set_version(1);
  c.set_issued_at_us(kDay0.count());
  c.add_signals("mc.status.motor_temp_c");
  c.mutable_trigger()->set_kind(v1::CAMPAIGN_TRIGGER_KIND_ALWAYS);
  c.mutable_sampling()->set_kind(v1::CAMPAIGN_SAMPLING_KIND_EVERY);
  c.mutable_sampling()->set_period_ms(1000);
  c.set_priority(5);
  c.set_disk_budget_bytes(1 << 20);
  c.set_start_us(kDay0.count());
  c.set_end_us((kDay0 + 10 * 86'400 * kSecond).count());
  c.mutable_target()->set_all_vehicles(true);
  return c;
}

inline CompiledCampaign compiled(const v1::Campaign& c) {
  auto r = compile_campaign(c);
  if (auto* e = std::get_if<std::string>(&r)) throw std::runtime_error(*e);
  return std::get<CompiledCampaign>(std::move(r));
}

// Builds, decodes and feeds frames to an engine; keeps the frames alive while decoded.
class TestBus {
 public:
  explicit TestBus(CampaignEngine& engine) : engine_(engine) {}

  void mc_temp(motinova::Micros t, double motor_temp_c) {
    feed(t, motinova::MessageWriter(*find("mc_status", 0x710), options_)
                .value("motor_temp_c", motor_temp_c)
                .frame());
  }
  // One raw field of mc_status (e.g. soc_pct 0xFF: "not available", decoded as invalid).
  void mc_status_raw(motinova::Micros t, std::string_view field, std::int64_t raw) {
    feed(t, motinova::MessageWriter(*find("mc_status", 0x710), options_).raw(field, raw).frame());
  }
  void bms_temp(motinova::Micros t, double temp_c) {
    feed(t, motinova::MessageWriter(*find("bms_status", 0x720), options_)
                .value("temp_c", temp_c)
                .frame());
  }
  void cells(motinova::Micros t, std::uint64_t base_mv) {
    motinova::MessageWriter w(*find("bms_cells", 0x720), options_);
    for (std::size_t i = 0; i < 16; ++i) w.element("cells_mv", i, base_mv + i);
    feed(t, w.frame());
  }
  void bms_faults(motinova::Micros t, std::int64_t word) {
    feed(t, motinova::MessageWriter(*find("bms_faults", 0x720), options_).raw("raw", word).frame());
  }
  void bms_firmware(motinova::Micros t, std::string_view fw) {
    feed(t, motinova::MessageWriter(*find("device_info", 0x720), options_).text("fw", fw).frame());
  }

  // Every sample of every record taken from the engine so far: (signal name, time, value).
  struct Got {
    std::string signal;
    motinova::Micros t;
    double value;
  };
  std::vector<Got> samples(std::vector<v1::CampaignSamples>* records = nullptr) {
    std::vector<Got> out;
    for (const auto& r : engine_.take_records()) {
      v1::CampaignSamples s;
      s.ParseFromString(r.payload);
      for (const auto& p : s.samples()) {
        out.push_back({s.signals(static_cast<int>(p.signal())),
                       motinova::Micros{s.base_us() + static_cast<std::int64_t>(p.offset_us())},
                       static_cast<double>(p.value_e6()) / 1e6});
      }
      if (records) records->push_back(s);
    }
    return out;
  }

 private:
  const motinova::MessageDesc* find(std::string_view name, std::uint16_t id) {
    return motinova::Catalogue::standard().find(name, id);
  }
  void feed(motinova::Micros t, motinova::AppFrame frame) {
    frames_.push_back(std::move(frame));
    motinova::DecodedMessage m;
    motinova::decode(frames_.back(), motinova::Catalogue::standard(), options_, m);
    engine_.on_message(t, m);
    if (frames_.size() > 4) frames_.pop_front();
  }

  CampaignEngine& engine_;
  motinova::DecodeOptions options_;
  std::deque<motinova::AppFrame> frames_;
};

}  // namespace fleetgw::campaign::test
