#include "tests/uplink/proto_compat.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/text_format.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include "proto/schema_reflection.h"

namespace fleetgw::testing {

namespace pb = google::protobuf;

namespace {

void collect(const pb::FileDescriptor* file,
             std::map<std::string, const pb::FileDescriptor*>& out) {
  if (file->package() != "fleetgw.v1" || out.contains(file->name())) return;
  out.emplace(file->name(), file);
  for (int i = 0; i < file->dependency_count(); ++i) collect(file->dependency(i), out);
}

std::string type_of(const pb::FieldDescriptorProto& f) {
  std::string t = pb::FieldDescriptor::TypeName(static_cast<pb::FieldDescriptor::Type>(f.type()));
  if (!f.type_name().empty()) t += " " + f.type_name();
  if (f.label() == pb::FieldDescriptorProto::LABEL_REPEATED) t = "repeated " + t;
  return t;
}

template <typename Proto>
bool number_reserved(const Proto& p, int number) {
  for (const auto& r : p.reserved_range()) {
    if (number >= r.start() && number < r.end()) return true;  // end is exclusive
  }
  return false;
}

template <typename Proto>
bool name_reserved(const Proto& p, const std::string& name) {
  return std::find(p.reserved_name().begin(), p.reserved_name().end(), name) !=
         p.reserved_name().end();
}

// Enum reserved ranges are inclusive at both ends (unlike message ranges).
bool enum_number_reserved(const pb::EnumDescriptorProto& e, int number) {
  for (const auto& r : e.reserved_range()) {
    if (number >= r.start() && number <= r.end()) return true;
  }
  return false;
}

std::string oneof_of(const pb::DescriptorProto& m, const pb::FieldDescriptorProto& f) {
  if (!f.has_oneof_index() || f.proto3_optional()) return "";
  return m.oneof_decl(f.oneof_index()).name();
}

class Comparer {
 public:
  std::vector<std::string> problems;

  void enums(const std::string& scope, const pb::RepeatedPtrField<pb::EnumDescriptorProto>& before,
             const pb::RepeatedPtrField<pb::EnumDescriptorProto>& after) {
    for (const auto& eb : before) {
      const std::string full = scope + "." + eb.name();
      const auto it = std::find_if(after.begin(), after.end(),
                                   [&](const auto& e) { return e.name() == eb.name(); });
      if (it == after.end()) {
        problems.push_back("enum " + full + " was removed");
        continue;
      }
      for (const auto& vb : eb.value()) {
        const auto va = std::find_if(it->value().begin(), it->value().end(),
                                     [&](const auto& v) { return v.number() == vb.number(); });
        if (va == it->value().end()) {
          if (!(enum_number_reserved(*it, vb.number()) && name_reserved(*it, vb.name()))) {
            problems.push_back("enum value " + full + "." + vb.name() + " (number " +
                               std::to_string(vb.number()) + ") was removed without `reserved " +
                               std::to_string(vb.number()) + "; reserved \"" + vb.name() + "\";`");
          }
        } else if (va->name() != vb.name()) {
          problems.push_back("enum value " + full + "." + vb.name() + " (number " +
                             std::to_string(vb.number()) + ") was renamed to " + va->name());
        }
      }
      for (const auto& va : it->value()) {
        const bool existed = std::any_of(eb.value().begin(), eb.value().end(),
                                         [&](const auto& v) { return v.number() == va.number(); });
        if (!existed && (enum_number_reserved(eb, va.number()) || name_reserved(eb, va.name()))) {
          problems.push_back("enum value " + full + "." + va.name() +
                             " reuses a reserved number "
                             "or name");
        }
      }
    }
  }

  void message(const std::string& full, const pb::DescriptorProto& b,
               const pb::DescriptorProto& a) {
    for (const auto& fb : b.field()) {
      const std::string path = full + "." + fb.name();
      const std::string number = std::to_string(fb.number());
      const auto by_number = std::find_if(a.field().begin(), a.field().end(),
                                          [&](const auto& f) { return f.number() == fb.number(); });
      const auto by_name = std::find_if(a.field().begin(), a.field().end(),
                                        [&](const auto& f) { return f.name() == fb.name(); });
      if (by_name != a.field().end() && by_name->number() != fb.number()) {
        problems.push_back("field " + path + " was renumbered from " + number + " to " +
                           std::to_string(by_name->number()));
        continue;
      }
      if (by_number == a.field().end()) {
        if (!(number_reserved(a, fb.number()) && name_reserved(a, fb.name()))) {
          problems.push_back("field " + path + " (number " + number +
                             ") was removed without `reserved " + number + "; reserved \"" +
                             fb.name() + "\";`");
        }
        continue;
      }
      if (by_number->name() != fb.name()) {
        problems.push_back("field " + path + " (number " + number + ") was renamed to " +
                           by_number->name() + " (breaks JSON and generated code)");
      }
      if (type_of(*by_number) != type_of(fb)) {
        problems.push_back("field " + path + " (number " + number + ") changed type from '" +
                           type_of(fb) + "' to '" + type_of(*by_number) + "'");
      }
      if (oneof_of(b, fb) != oneof_of(a, *by_number)) {
        problems.push_back("field " + path + " (number " + number + ") moved from oneof '" +
                           oneof_of(b, fb) + "' to oneof '" + oneof_of(a, *by_number) + "'");
      }
      if (fb.proto3_optional() != by_number->proto3_optional()) {
        problems.push_back("field " + path + " (number " + number +
                           ") changed presence (optional added or removed)");
      }
    }
    for (const auto& fa : a.field()) {
      const bool existed = std::any_of(b.field().begin(), b.field().end(),
                                       [&](const auto& f) { return f.number() == fa.number(); });
      if (!existed && (number_reserved(b, fa.number()) || name_reserved(b, fa.name()))) {
        problems.push_back("field " + full + "." + fa.name() + " (number " +
                           std::to_string(fa.number()) + ") reuses a reserved number or name");
      }
    }
    messages(full, b.nested_type(), a.nested_type());
    enums(full, b.enum_type(), a.enum_type());
  }

  void messages(const std::string& scope, const pb::RepeatedPtrField<pb::DescriptorProto>& before,
                const pb::RepeatedPtrField<pb::DescriptorProto>& after) {
    for (const auto& mb : before) {
      if (mb.options().map_entry()) continue;  // compared through the map field's type
      const std::string full = scope + "." + mb.name();
      const auto it = std::find_if(after.begin(), after.end(),
                                   [&](const auto& m) { return m.name() == mb.name(); });
      if (it == after.end()) {
        problems.push_back("message " + full + " was removed");
        continue;
      }
      message(full, mb, *it);
    }
  }
};

}  // namespace

pb::FileDescriptorSet current_fleetgw_descriptors() {
  // The generated classes are lite; the schema compiled into the binary is the same protoc run.
  static const proto::SchemaReflection schema;
  std::map<std::string, const pb::FileDescriptor*> files;
  // envelope.proto imports every other file of the package, so this reaches them all; the
  // command messages that never travel inside an Envelope are named explicitly all the same.
  collect(schema.message_type("fleetgw.v1.Envelope").file(), files);
  collect(schema.message_type("fleetgw.v1.SignedCommand").file(), files);
  pb::FileDescriptorSet set;
  for (const auto& [name, file] : files) file->CopyTo(set.add_file());
  return set;
}

std::string to_snapshot_text(const pb::FileDescriptorSet& set) {
  std::string out;
  pb::TextFormat::PrintToString(set, &out);
  return out;
}

pb::FileDescriptorSet from_snapshot_text(const std::string& text) {
  pb::FileDescriptorSet set;
  if (!pb::TextFormat::ParseFromString(text, &set)) {
    throw std::runtime_error("descriptor snapshot is not a valid text-format FileDescriptorSet");
  }
  return set;
}

std::vector<std::string> compare(const pb::FileDescriptorSet& before,
                                 const pb::FileDescriptorSet& after) {
  Comparer c;
  // Types may move between files of the package without harm, so compare package-wide.
  pb::DescriptorProto all_before, all_after;
  pb::RepeatedPtrField<pb::EnumDescriptorProto> enums_before, enums_after;
  for (const auto& f : before.file()) {
    for (const auto& m : f.message_type()) *all_before.add_nested_type() = m;
    for (const auto& e : f.enum_type()) *enums_before.Add() = e;
  }
  for (const auto& f : after.file()) {
    for (const auto& m : f.message_type()) *all_after.add_nested_type() = m;
    for (const auto& e : f.enum_type()) *enums_after.Add() = e;
  }
  c.messages("fleetgw.v1", all_before.nested_type(), all_after.nested_type());
  c.enums("fleetgw.v1", enums_before, enums_after);
  return c.problems;
}

pb::FileDescriptorSet load_snapshot(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read the schema snapshot " + path);
  std::ostringstream text;
  text << in.rdbuf();
  return from_snapshot_text(text.str());
}

const pb::FieldDescriptorProto* find_field(const pb::FileDescriptorSet& set,
                                           std::string_view message, std::string_view name) {
  for (const auto& f : set.file()) {
    for (const auto& m : f.message_type()) {
      if (m.name() != message) continue;
      for (const auto& field : m.field()) {
        if (field.name() == name) return &field;
      }
    }
  }
  return nullptr;
}

std::string build_pool(const pb::FileDescriptorSet& set, pb::DescriptorPool& pool) {
  std::vector<const pb::FileDescriptorProto*> pending;
  for (const auto& f : set.file()) pending.push_back(&f);
  std::string errors;
  while (!pending.empty()) {
    const std::size_t before = pending.size();
    std::erase_if(pending, [&](const pb::FileDescriptorProto* f) {
      for (const auto& dep : f->dependency()) {
        if (pool.FindFileByName(dep) == nullptr) return false;
      }
      if (pool.BuildFile(*f) == nullptr) errors += "cannot build " + f->name() + "; ";
      return true;
    });
    if (pending.size() == before)
      return errors + "unresolvable imports in " + pending.front()->name();
  }
  return errors;
}

}  // namespace fleetgw::testing
