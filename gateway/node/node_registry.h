// What the IoT node knows about every other node on the bus: present or not, first/last heard,
// online/offline, model info, fault-word state and the latest copy of every message it sent.
//
// Contract:
//  * Fed with every received application frame (on_frame) and a periodic tick(now); never reads
//    a clock. A node is identified by the source nibble of the CAN ID (§1.2), so answers on
//    directed IDs (0x713, 0x725) count as the MC/BMS being heard.
//  * All 16 node numbers are tracked, so the CDL, the legacy HMI and reserved numbers show up
//    when they talk. Frames from node 6 (IOT) are someone else claiming our node number (or the
//    transport echoing our own frames) and are recorded like any other.
//  * Online: heard within `offline_timeout`. A node goes offline in tick() once that much time
//    has passed since its last frame, and online again on its next frame. Observers are told of
//    each transition exactly once.
//  * Fault words (MessageKind::kFaultWord): kOk for an all-zero word, kFaulty otherwise, and
//    kUnknown when none was heard for `fault_stale_timeout` (§3.7: missing is not "OK") or never.
//    The last raw word is kept even when the state is kUnknown. Observers get every state change
//    and every change of the raw word.
//  * Latest message per (CAN ID, function): a value copy of the AppFrame and its receive time,
//    so readers never hold views into buffers that the reassembler reuses.
//  * Observers are non-owning; remove them before they die. Callbacks run synchronously inside
//    on_frame()/tick(); they must not add or remove observers.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "motinova/can.h"
#include "motinova/codec.h"
#include "motinova/frame.h"

namespace fleetgw::node {

using motinova::Micros;
using motinova::Node;

enum class FaultState : uint8_t { kUnknown, kOk, kFaulty };
std::string_view fault_state_name(FaultState s);  // "unknown", "ok", "faulty"

struct FaultWordState {
  FaultState state = FaultState::kUnknown;
  std::optional<uint32_t> raw;  // last word heard (kept when it goes stale)
  Micros heard{0};              // when `raw` was heard
  friend bool operator==(const FaultWordState&, const FaultWordState&) = default;
};

struct ModelInfo {
  std::string model, serial, hw, fw;
  Micros heard{0};
  friend bool operator==(const ModelInfo&, const ModelInfo&) = default;
};

struct MessageSnapshot {
  std::string name;  // catalogue name ("mc_status", "unknown" ...)
  motinova::AppFrame frame;
  Micros received{0};
};

struct NodeState {
  Node node = Node::kBroadcast;
  bool present = false;  // heard at least once
  bool online = false;
  Micros first_heard{0};
  Micros last_heard{0};
  uint64_t frames = 0;
  std::optional<ModelInfo> model;
  FaultWordState faults;
  // (can_id << 8 | function) -> latest copy.
  std::map<uint32_t, MessageSnapshot> latest;

  const MessageSnapshot* find(uint16_t can_id, uint8_t function) const;
  const MessageSnapshot* find(std::string_view name) const;  // first with this name
};

class RegistryObserver {
 public:
  virtual ~RegistryObserver() = default;
  virtual void on_node_online(Node /*node*/, Micros /*now*/) {}
  virtual void on_node_offline(Node /*node*/, Micros /*last_heard*/, Micros /*now*/) {}
  virtual void on_fault_word(Node /*node*/, const FaultWordState& /*before*/,
                             const FaultWordState& /*after*/, Micros /*now*/) {}
  virtual void on_model_info(Node /*node*/, const ModelInfo& /*info*/, Micros /*now*/) {}
};

struct RegistryConfig {
  Micros offline_timeout{3'000'000};
  Micros fault_stale_timeout{2'000'000};
};

class NodeRegistry {
 public:
  explicit NodeRegistry(RegistryConfig config);

  void on_frame(const motinova::AppFrame& frame, const motinova::DecodedMessage& msg, Micros now);
  void tick(Micros now);
  // When tick() next has something to do: a node going offline or a fault word going stale
  // (Micros::max(): never).
  Micros next_event() const;

  const NodeState& node(Node n) const { return nodes_[static_cast<std::size_t>(n) & 0xF]; }
  bool online(Node n) const { return node(n).online; }
  // The fault-word state as of `now` (stale words read as kUnknown even before the next tick).
  FaultWordState fault_word(Node n, Micros now) const;
  // Nodes heard at least once, in node-number order.
  std::vector<Node> present_nodes() const;

  void add_observer(RegistryObserver& observer);
  void remove_observer(RegistryObserver& observer);

  const RegistryConfig& config() const { return config_; }

 private:
  void set_faults(NodeState& s, FaultWordState next, Micros now);

  RegistryConfig config_;
  std::array<NodeState, 16> nodes_;
  std::vector<RegistryObserver*> observers_;
};

}  // namespace fleetgw::node
