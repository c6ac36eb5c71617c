#include "gateway/campaign/signals_command.h"

#include <fmt/format.h>

#include <ostream>

#include "gateway/common/table_format.h"
#include "motinova/signal_catalogue.h"

namespace fleetgw::campaign {

int run_signals(bool json, std::ostream& out) {
  common::Table table;
  table.columns = {{"name", "SIGNAL"},     {"type", "TYPE"},       {"unit", "UNIT"},
                   {"node", "NODE"},       {"message", "MESSAGE"}, {"can_id", "ID"},
                   {"command", "COMMAND"}, {"title", "TITLE"}};
  for (const motinova::Signal& s : motinova::SignalCatalogue::standard().signals()) {
    const motinova::MessageDesc& m = *s.message;
    table.rows.push_back({s.name, std::string(motinova::signal_type_name(s.type)),
                          std::string(s.unit), std::string(motinova::node_name(m.source())),
                          std::string(m.name), fmt::format("0x{:03X}", m.can_id),
                          fmt::format("0x{:04X}", m.command()), std::string(m.title)});
  }
  common::write_as(json ? common::OutputFormat::kJson : common::OutputFormat::kTable, table, out);
  return 0;
}

}  // namespace fleetgw::campaign
