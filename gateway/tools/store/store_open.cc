#include "gateway/tools/store/store_open.h"

#include "storage/schema.h"

namespace fleetgw::tools {

int open_store_read_only(storage::StoreOptions options, std::string_view command,
                         std::optional<storage::Store>& store, std::ostream& err) {
  options.read_only = true;
  try {
    store.emplace(std::move(options));
  } catch (const storage::NotAStoreError& e) {
    err << "fleetgw " << command << ": " << e.what() << '\n';
    return 2;
  } catch (const storage::SchemaTooNewError& e) {
    err << "fleetgw " << command << ": " << e.what() << '\n';
    return 1;
  }
  return 0;
}

}  // namespace fleetgw::tools
