// Test support: whole text files and their lines, the one implementation of the suites (a test
// reads a child's output, a config or a log it wrote; nothing here is a fixed wait).
//
// Contract: read_text_file() is the file's whole content, "" when it cannot be read (a test's
// expectation on it then fails, naming the text); write_text_file() replaces the file's content
// (std::runtime_error names a file that cannot be written); lines_of() cuts text at its
// newlines, a last line without one included.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fleetgw::testing {

inline std::string read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

inline void write_text_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

}  // namespace fleetgw::testing
