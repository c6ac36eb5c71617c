#include "gateway/uplink/uplink_status.h"

namespace fleetgw::uplink {

void fill_status(v1::Status& status, const UplinkStats& stats) {
  status.set_last_publish_ok_at_us(stats.last_publish_ok_us);
  status.set_last_connect_error(stats.last_connect_error);
  status.set_last_connect_error_at_us(stats.last_connect_error_us);
  status.set_tls_failures(stats.tls_failures);
  status.set_publish_refusals(stats.publish_refusals);
  status.set_last_publish_refusal(stats.last_publish_refusal);
  status.set_last_publish_refusal_code(static_cast<std::uint32_t>(stats.last_publish_refusal_code));
  status.set_last_publish_refusal_at_us(stats.last_publish_refusal_us);
}

}  // namespace fleetgw::uplink
