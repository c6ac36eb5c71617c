// JSON text for the few jsonb columns of a record row (a vehicle state's locks and faults, a
// device info's nodes), written straight into a string (issue 25): building an nlohmann::json
// document first cost a dozen allocations per entry and ~7 % of the worker's CPU in a drain,
// a state being every other message.
//
// Contract:
//  * The text is what nlohmann::json's dump(-1, ' ', false, error_handler_t::replace) gives for
//    the same document: no spaces, object keys in the order the caller writes them (callers write
//    them sorted, as nlohmann's std::map does), `"` `\` and control characters escaped (`\b`
//    `\f` `\n` `\r` `\t`, else `\u00xx`), other bytes as they are.
//  * A string that is not valid UTF-8 (not from a proto3 sender) is written by nlohmann itself,
//    whose `replace` handler turns its invalid bytes into U+FFFD: jsonb accepts only valid text.
//  * JsonWriter: begin_array/end_array, begin_object/end_object, key() before each member's
//    value, string/number/null values; commas are its own. Misuse (a value without a key in an
//    object) is the caller's bug: not checked.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace fleetgw::ingest {

void append_json_string(std::string& out, std::string_view s);

class JsonWriter {
 public:
  explicit JsonWriter(std::string& out) : out_(out) {}
  void begin_array() { open('['); }
  void end_array() { close(']'); }
  void begin_object() { open('{'); }
  void end_object() { close('}'); }
  void key(std::string_view k) {
    comma();
    append_json_string(out_, k);
    out_ += ':';
    first_ = true;  // the member's value takes no comma
  }
  void string(std::string_view s) {
    comma();
    append_json_string(out_, s);
  }
  void number(std::uint64_t v);
  void null() {
    comma();
    out_ += "null";
  }

 private:
  void comma() {
    if (!first_) out_ += ',';
    first_ = false;
  }
  void open(char c) {
    comma();
    out_ += c;
    first_ = true;
  }
  void close(char c) {
    out_ += c;
    first_ = false;
  }

  std::string& out_;
  bool first_ = true;
};

}  // namespace fleetgw::ingest
