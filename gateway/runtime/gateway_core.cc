#include "gateway/runtime/gateway_core.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "gateway/runtime/clock_units.h"

namespace fleetgw::runtime {
node::NodeConfig make_node_config(const config::Config& c) {
  node::NodeConfig n;
  n.identity.model = c.node.identity.model;
  n.identity.serial = c.node.identity.serial;
  n.identity.hardware = c.node.identity.hw;
  n.offline_timeout = ms(c.node.offline_timeout_ms);
  n.fault_stale_timeout = ms(c.node.fault_stale_ms);
  n.requests.retry_interval = ms(c.node.request_retry_ms);
  n.requests.timeout = ms(c.node.request_timeout_ms);
  n.broadcasts.model_info_period = ms(c.node.model_info_period_ms);
  n.locks.timeout = ms(c.command.confirm_timeout_ms);
  for (std::size_t k = 0; k < n.fitted_locks.size(); ++k) {
    n.fitted_locks[k] = !c.protocol.lock_kinds[k].empty();
  }
  auto table = n.effective_poll_table();
  for (auto& e : table) {
    if (e.period == Micros(0)) continue;  // once-entries (model info) stay as they are
    if (e.name == "bms_pack_stats") {
      e.period = ms(c.node.pack_stats_poll_ms);
    } else if (e.name.starts_with("lock") && e.name.ends_with("_status")) {
      e.period = ms(c.node.lock_status_poll_ms);
    } else if (e.name == "bms_status" || e.name == "bms_cells" || e.name == "bms_faults") {
      e.period = ms(c.node.bms_poll_ms);
    }
  }
  n.poll_table = std::move(table);
  return n;
}

GatewayCore::GatewayCore(const config::Config& config, node::FrameSender& sender,
                         node::NodeHooks hooks)
    : options_(config.protocol),
      reassembler_(motinova::ReassemblerOptions{.gap_timeout = ms(config.can.reassembly_gap_ms),
                                                .crc_order = config.protocol.crc_order}),
      echo_(sender, *this),
      own_(motinova::Catalogue::standard(), options_),
      node_(std::make_unique<node::IotNode>(make_node_config(config), options_, echo_,
                                            std::move(hooks))) {
  live_.settings_limit_is_factory = config.command.mc_settings_limit == "factory";
}

bool GatewayCore::EchoSender::send(const motinova::AppFrame& frame) {
  if (!inner_.send(frame)) return false;
  // Nothing refers to the table between deliveries: the only moment it may be trimmed.
  if (core_.echoes_.empty()) core_.own_.trim();
  core_.echoes_.push_back(&core_.own_.intern(frame));
  core_.stats_.echo_decodes = core_.own_.decodes();
  return true;
}

void GatewayCore::deliver_echoes() {
  if (delivering_echoes_) return;  // the outer delivery loop picks up what was added
  delivering_echoes_ = true;
  // Index loop: a listener's reaction to an echo may transmit (and so append) again.
  // Entries stay put while echoes are pending (OwnMessages::trim only runs on an empty queue).
  for (std::size_t i = 0; i < echoes_.size(); ++i) {
    const motinova::DecodedMessage& message = echoes_[i]->decoded;
    ++stats_.echoes;
    for (auto* l : listeners_) l->on_message(message, now_);
  }
  echoes_.clear();
  delivering_echoes_ = false;
  // Whoever made the node send (or start something) calls this afterwards.
  node_due_stale_ = true;
}

Micros GatewayCore::node_deadline() const {
  if (node_due_stale_) {
    node_due_ = node_->next_event();
    node_due_stale_ = false;
  }
  return node_due_;
}

Micros GatewayCore::next_event() const {
  return std::min(node_deadline(), listeners_due_);
}

GatewayCore::~GatewayCore() = default;

void GatewayCore::start(Micros now) {
  now_ = now;
  node_->start(now);
  deliver_echoes();
  last_tick_ = now;
  listeners_due_ = now + kTickInterval;
}

void GatewayCore::on_can_frame(const motinova::CanFrame& frame, Micros timestamp) {
  if (!traffic_since_tick_) {
    // The bus came back: listeners return to the flowing cadence.
    traffic_since_tick_ = true;
    listeners_due_ = std::min(listeners_due_, last_tick_ + kTickInterval);
  }
  if (timestamp >= next_event()) tick(timestamp);
  now_ = std::max(now_, timestamp);
  reassembler_.push(frame, timestamp, *this);
  deliver_echoes();
}

void GatewayCore::on_frame(const motinova::AppFrame& frame, Micros ts) {
  motinova::decode(frame, motinova::Catalogue::standard(), options_, decoded_);
  ++stats_.messages;
  if (decoded_.status == motinova::DecodeStatus::kUnknownMessage) ++stats_.unknown_messages;
  if (decoded_.status == motinova::DecodeStatus::kLengthMismatch) {
    ++stats_.length_mismatches;
    spdlog::warn(
        "bus: 0x{:03X} function 0x{:02X} has {} data bytes, the catalogue expects another "
        "length; kept as unknown",
        frame.can_id, frame.function, frame.data.size());
  }
  node_->on_frame(frame, decoded_, ts);
  node_due_stale_ = true;
  live_.update(decoded_, options_);
  for (auto* l : listeners_) l->on_message(decoded_, ts);
  // The gateway's reactions to this frame (answers, lock commands) come after it.
  deliver_echoes();
}

void GatewayCore::on_error(const motinova::ReassemblyErrorEvent& e) {
  // Bus errors are data, not failures: count them, and log at most one summary per second so a
  // noisy bus cannot flood the journal.
  ++errors_since_log_;
  if (e.timestamp - last_error_log_ >= Micros(1'000'000)) {
    spdlog::warn(
        "bus: {} frame error(s) in the last second, latest {} on 0x{:03X} ({} bytes dropped)",
        errors_since_log_, motinova::reassembly_error_name(e.kind), e.can_id, e.bytes_dropped);
    last_error_log_ = e.timestamp;
    errors_since_log_ = 0;
  }
}

void GatewayCore::tick(Micros now) {
  now_ = std::max(now_, now);
  reassembler_.expire(now, *this);
  node_->tick(now);
  deliver_echoes();
  for (auto* l : listeners_) l->tick(now);
  deliver_echoes();
  last_tick_ = now;
  listeners_due_ = now + (traffic_since_tick_ ? kTickInterval : kIdleTickInterval);
  traffic_since_tick_ = false;
  node_due_stale_ = true;
}

}  // namespace fleetgw::runtime
