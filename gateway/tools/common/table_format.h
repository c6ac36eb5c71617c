// The `--format table|json|csv` writers of the inspection commands, under the CLI's namespace.
// They live in gateway/common/table_format.h (contract there), because `fleetgw decode` prints
// its summary with them too and the decode area must not depend on app.
#pragma once

#include "gateway/common/table_format.h"

namespace fleetgw::tools {

using common::Column;
using common::csv_field;
using common::flatten;
using common::OutputFormat;
using common::parse_output_format;
using common::Table;
using common::table_cell;
using common::write_as;
using common::write_csv;
using common::write_json;
using common::write_table;

}  // namespace fleetgw::tools
