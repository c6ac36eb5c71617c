#include "gateway/runtime/device_info_reporter.h"

#include "fleetgw/v1/device_info.pb.h"
#include "motinova/can.h"

namespace fleetgw::runtime {
namespace {

// Bus text is untrusted: anything but printable ASCII becomes '?', so the record is valid UTF-8
// (a protobuf string) whatever a node sends.
std::string printable(const std::string& text) {
  std::string out = text;
  for (char& c : out) {
    if (c < 0x20 || c > 0x7E) c = '?';
  }
  return out;
}

}  // namespace

std::optional<std::string> DeviceInfoReporter::take(const node::NodeRegistry& registry) {
  if (!due_) return std::nullopt;
  due_ = false;
  v1::DeviceInfo info;
  v1::NodeInfo* own = info.add_nodes();
  own->set_node(std::string(motinova::node_name(motinova::Node::kIot)));
  own->set_model(own_.model);
  own->set_serial(own_.serial);
  own->set_hw_version(own_.hardware);
  try {
    own->set_fw_version(own_.firmware());
  } catch (const std::exception&) {
    own->set_fw_version(own_.firmware_version);  // validated at start-up; never expected
  }
  for (const node::Node n : registry.present_nodes()) {
    const node::NodeState& s = registry.node(n);
    // Node 6 heard on the bus is our own echo or an impostor: the configured identity stands.
    if (!s.model || n == motinova::Node::kIot) continue;
    v1::NodeInfo* e = info.add_nodes();
    e->set_node(std::string(motinova::node_name(n)));
    e->set_model(printable(s.model->model));
    e->set_serial(printable(s.model->serial));
    e->set_hw_version(printable(s.model->hw));
    e->set_fw_version(printable(s.model->fw));
  }
  return info.SerializeAsString();
}

}  // namespace fleetgw::runtime
