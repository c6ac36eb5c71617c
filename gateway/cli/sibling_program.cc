#include "gateway/cli/sibling_program.h"

#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace fleetgw::cli {

int exec_subcommand_program(std::string_view program_name, std::string_view command, int argc,
                            char** argv) {
  int first = 1;
  while (first < argc && std::string_view(argv[first]) != command) ++first;
  std::string program(program_name);
  std::vector<char*> args;
  args.push_back(program.data());
  for (int i = first + 1; i < argc; ++i) args.push_back(argv[i]);
  args.push_back(nullptr);
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::string sibling = (self.parent_path() / program).string();
    ::execv(sibling.c_str(), args.data());
  }
  ::execvp(program.c_str(), args.data());
  std::cerr << "fleetgw " << command << ": cannot run " << program << " (not next to "
            << (ec ? std::string("fleetgw") : self.string()) << " nor on PATH)\n";
  return 127;
}

}  // namespace fleetgw::cli
