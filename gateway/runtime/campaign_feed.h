// The campaigns as a listener of the core (issue 29): every decoded message and tick goes to the
// CampaignService on the bus timeline, and the records it cuts are queued through the recorder
// (the same outbox, the same flush discipline as device info). Every 5 s of wall time at most it
// tells the service what the store holds at the campaign priority (their disk budgets).
#pragma once

#include <chrono>

#include "env/env.h"
#include "gateway/campaign/campaign_service.h"
#include "gateway/runtime/clock_units.h"
#include "gateway/runtime/gateway_core.h"
#include "gateway/runtime/recorder.h"
#include "storage/store.h"

namespace fleetgw::runtime {

class CampaignFeed final : public MessageListener {
 public:
  CampaignFeed(campaign::CampaignService& service, Recorder& recorder, storage::Store& store,
               Env& env)
      : service_(service), recorder_(recorder), store_(store), env_(env) {}

  void on_message(const motinova::DecodedMessage& m, Micros t) override {
    service_.on_message(t, m);
    drain();
  }
  void tick(Micros t) override {
    // A campaign's start and end are judged on the bike's clock, as its windows (a replay of an
    // old log runs the campaigns of its time).
    service_.tick(t, t);
    const Micros wall = env_.wall_now();
    if (wall - last_depth_ >= std::chrono::seconds(5)) {
      last_depth_ = wall;
      service_.store_holds(store_.outbox_depth());
    }
    drain();
  }

 private:
  void drain() {
    for (auto& m : service_.take_messages()) recorder_.queue_message(std::move(m));
  }

  campaign::CampaignService& service_;
  Recorder& recorder_;
  storage::Store& store_;
  Env& env_;
  Micros last_depth_{0};
};

}  // namespace fleetgw::runtime
