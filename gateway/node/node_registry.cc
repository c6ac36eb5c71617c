#include "gateway/node/node_registry.h"

#include <algorithm>
#include <utility>

namespace fleetgw::node {
namespace {

uint32_t key_of(uint16_t can_id, uint8_t function) {
  return (static_cast<uint32_t>(can_id) << 8) | function;
}

}  // namespace

std::string_view fault_state_name(FaultState s) {
  switch (s) {
    case FaultState::kUnknown:
      return "unknown";
    case FaultState::kOk:
      return "ok";
    case FaultState::kFaulty:
      return "faulty";
  }
  return "?";
}

const MessageSnapshot* NodeState::find(uint16_t can_id, uint8_t function) const {
  const auto it = latest.find(key_of(can_id, function));
  return it == latest.end() ? nullptr : &it->second;
}

const MessageSnapshot* NodeState::find(std::string_view name) const {
  for (const auto& [key, snap] : latest) {
    if (snap.name == name) return &snap;
  }
  return nullptr;
}

NodeRegistry::NodeRegistry(RegistryConfig config) : config_(config) {
  for (std::size_t i = 0; i < nodes_.size(); ++i) nodes_[i].node = static_cast<Node>(i);
}

void NodeRegistry::on_frame(const motinova::AppFrame& frame, const motinova::DecodedMessage& msg,
                            Micros now) {
  if (!motinova::is_motinova_id(frame.can_id)) return;
  NodeState& s = nodes_[static_cast<std::size_t>(motinova::source_of(frame.can_id))];
  if (!s.present) {
    s.present = true;
    s.first_heard = now;
  }
  s.last_heard = now;
  ++s.frames;
  // Online first, so observers see "online" before the content that came with it.
  if (!s.online) {
    s.online = true;
    for (RegistryObserver* o : observers_) o->on_node_online(s.node, now);
  }

  // Value copy: the DecodedMessage's views die with the caller's AppFrame.
  MessageSnapshot& snap = s.latest[key_of(frame.can_id, frame.function)];
  if (snap.name != msg.name()) snap.name = std::string(msg.name());
  snap.frame = frame;
  snap.received = now;

  const bool known = msg.desc != nullptr && msg.status == motinova::DecodeStatus::kOk;
  if (known && msg.desc->kind == motinova::MessageKind::kModelInfo) {
    ModelInfo info{std::string(msg.text("model")), std::string(msg.text("serial")),
                   std::string(msg.text("hw")), std::string(msg.text("fw")), now};
    const bool changed = !s.model || s.model->model != info.model ||
                         s.model->serial != info.serial || s.model->hw != info.hw ||
                         s.model->fw != info.fw;
    s.model = std::move(info);
    if (changed) {
      for (RegistryObserver* o : observers_) o->on_model_info(s.node, *s.model, now);
    }
  }
  if (known && msg.desc->kind == motinova::MessageKind::kFaultWord) {
    std::optional<int64_t> raw = msg.raw("raw");
    if (!raw && !msg.values().empty()) raw = msg.values().front().raw;
    if (raw) {
      const auto word = static_cast<uint32_t>(*raw);
      set_faults(s, {word == 0 ? FaultState::kOk : FaultState::kFaulty, word, now}, now);
    }
  }
}

void NodeRegistry::tick(Micros now) {
  for (NodeState& s : nodes_) {
    if (s.online && now - s.last_heard >= config_.offline_timeout) {
      s.online = false;
      for (RegistryObserver* o : observers_) o->on_node_offline(s.node, s.last_heard, now);
    }
    if (s.faults.state != FaultState::kUnknown &&
        now - s.faults.heard >= config_.fault_stale_timeout) {
      FaultWordState next = s.faults;
      next.state = FaultState::kUnknown;
      set_faults(s, next, now);
    }
  }
}

Micros NodeRegistry::next_event() const {
  Micros next = Micros::max();
  for (const NodeState& s : nodes_) {
    if (s.online) next = std::min(next, s.last_heard + config_.offline_timeout);
    if (s.faults.state != FaultState::kUnknown) {
      next = std::min(next, s.faults.heard + config_.fault_stale_timeout);
    }
  }
  return next;
}

FaultWordState NodeRegistry::fault_word(Node n, Micros now) const {
  FaultWordState f = node(n).faults;
  if (f.state != FaultState::kUnknown && now - f.heard >= config_.fault_stale_timeout) {
    f.state = FaultState::kUnknown;
  }
  return f;
}

std::vector<Node> NodeRegistry::present_nodes() const {
  std::vector<Node> out;
  for (const NodeState& s : nodes_) {
    if (s.present) out.push_back(s.node);
  }
  return out;
}

void NodeRegistry::add_observer(RegistryObserver& observer) {
  if (std::find(observers_.begin(), observers_.end(), &observer) == observers_.end()) {
    observers_.push_back(&observer);
  }
}

void NodeRegistry::remove_observer(RegistryObserver& observer) {
  std::erase(observers_, &observer);
}

void NodeRegistry::set_faults(NodeState& s, FaultWordState next, Micros now) {
  const FaultWordState before = s.faults;
  s.faults = next;
  // A repeat of the same word only refreshes `heard`; observers care about state/word changes.
  if (before.state == next.state && before.raw == next.raw) return;
  for (RegistryObserver* o : observers_) o->on_fault_word(s.node, before, next, now);
}

}  // namespace fleetgw::node
