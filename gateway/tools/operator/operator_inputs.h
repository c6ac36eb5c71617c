// What the operator tools (`fleetgw command`, `fleetgw keys publish-revocations`) read from their
// command line the same way: a document `fleetgw keys` signed, from its file, and the broker
// options.
//
// Contract:
//  * read_signed_file<Signed, Document>(file, signed_part, what, error): the file's exact bytes
//    (a tool sends them on unchanged: the signature covers them) and the document they sign
//    (signed_part(the file parsed as Signed), parsed as Document). nullopt, with `error` set,
//    when the file cannot be read ("cannot read <file>") or is empty, is not a Signed, signs
//    nothing, or what it signs is not a Document ("<file> is not <what>"). The document's own
//    rules (a key id, a version) are the caller's.
//  * broker_option_error(...): the usage error of broker options that are refused -- a URI that
//    is not tcp:// or ssl://, credentials in the URI, a user name or password over plain tcp://
//    unless explicitly allowed; nullopt when they are fine.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace fleetgw::tools {

// The whole of `file`; nullopt when it cannot be opened or read.
std::optional<std::string> read_file_bytes(const std::filesystem::path& file);

template <class Document>
struct SignedFile {
  std::string bytes;  // the file as it is: the serialized signed message
  Document document;  // what it signs
};

template <class Signed, class Document, class SignedPart>
std::optional<SignedFile<Document>> read_signed_file(const std::filesystem::path& file,
                                                     SignedPart signed_part, std::string_view what,
                                                     std::string& error) {
  auto bytes = read_file_bytes(file);
  if (!bytes) {
    error = "cannot read " + file.string();
    return std::nullopt;
  }
  Signed outer;
  SignedFile<Document> out;
  if (bytes->empty() || !outer.ParseFromString(*bytes) || signed_part(outer).empty() ||
      !out.document.ParseFromString(signed_part(outer))) {
    error = file.string() + " is not " + std::string(what);
    return std::nullopt;
  }
  out.bytes = std::move(*bytes);
  return out;
}

std::optional<std::string> broker_option_error(const std::string& broker,
                                               const std::string& username,
                                               const std::string& password,
                                               bool allow_plaintext_credentials);

}  // namespace fleetgw::tools
