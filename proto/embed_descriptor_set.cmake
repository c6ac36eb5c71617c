# cmake -DIN=<descriptor set> -DOUT=<.cc> -P embed_descriptor_set.cmake
# Writes the bytes of IN as the definition of fleetgw::proto::descriptor_set_bytes().
file(READ "${IN}" hex HEX)
string(LENGTH "${hex}" hex_length)
math(EXPR size "${hex_length} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
string(REGEX REPLACE "((0x[0-9a-f][0-9a-f],){16})" "\\1\n    " bytes "${bytes}")
file(WRITE "${OUT}.tmp" "// Generated from ${IN} by proto/embed_descriptor_set.cmake. Do not edit.
#include \"proto/descriptor_set.h\"

namespace fleetgw::proto {
namespace {
constexpr unsigned char kBytes[${size}] = {
    ${bytes}};
}  // namespace

std::string_view descriptor_set_bytes() {
  return {reinterpret_cast<const char*>(kBytes), sizeof kBytes};
}

}  // namespace fleetgw::proto
")
file(RENAME "${OUT}.tmp" "${OUT}")
