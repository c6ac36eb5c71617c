#include "gateway/cli/completion.h"

#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::cli {
namespace {

// One command path of the completion tables.
struct CompletionPath {
  std::string path;  // "" for fleetgw itself, "db rides" for `fleetgw db rides`
  std::vector<std::string> subcommands;
  std::vector<std::string> options;  // --long and -s names
  // Options that take a value, each with the values CLI11 enumerates for it (may be empty).
  std::vector<std::pair<std::string, std::vector<std::string>>> valued;
  bool positional = false;
};

bool completion_word_ok(std::string_view w) {
  if (w.empty()) return false;
  for (const char c : w) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    std::string_view("_.,:+@%/-").find(c) != std::string_view::npos;
    if (!ok) return false;
  }
  return true;
}

// The members of every "{a,b,c}" set in an option's type text (CLI11 writes each validator's
// description after the type: "TEXT:{be,le,auto}"; a transformer map as "{key->value,...}").
std::vector<std::string> enumerated_values(const std::string& type_name) {
  std::vector<std::string> values;
  for (std::size_t open = type_name.find('{'); open != std::string::npos;
       open = type_name.find('{', open + 1)) {
    const std::size_t close = type_name.find('}', open);
    if (close == std::string::npos) break;
    std::string_view set(type_name.data() + open + 1, close - open - 1);
    while (!set.empty()) {
      const std::size_t comma = set.find(',');
      std::string_view item = set.substr(0, comma);
      item = item.substr(0, item.find("->"));
      if (completion_word_ok(item)) values.emplace_back(item);
      if (comma == std::string_view::npos) break;
      set.remove_prefix(comma + 1);
    }
    open = close;
  }
  return values;
}

void add_completion_options(const CLI::App& app, CompletionPath& p) {
  for (const CLI::Option* opt : app.get_options()) {
    if (opt->get_group().empty()) continue;  // hidden
    if (!opt->nonpositional()) {
      p.positional = true;
      continue;
    }
    const bool takes_value = opt->get_type_size() != 0 && opt->get_expected_max() != 0;
    const auto values =
        takes_value ? enumerated_values(opt->get_type_name()) : std::vector<std::string>{};
    auto add = [&](const std::string& name) {
      if (!completion_word_ok(name)) return;
      p.options.push_back(name);
      if (takes_value) p.valued.emplace_back(name, values);
    };
    for (const auto& l : opt->get_lnames()) add("--" + l);
    for (const auto& s : opt->get_snames()) add("-" + s);
  }
}

void collect_completion_paths(const CLI::App& app, const std::string& path,
                              std::vector<CompletionPath>& out) {
  const std::size_t index = out.size();
  out.push_back({});
  out[index].path = path;
  add_completion_options(app, out[index]);
  const auto subs = app.get_subcommands([](const CLI::App* s) { return !s->get_group().empty(); });
  for (const CLI::App* sub : subs) {
    if (sub->get_name().empty()) {  // an option group: its options are the command's
      add_completion_options(*sub, out[index]);
      continue;
    }
    if (!completion_word_ok(sub->get_name())) continue;
    out[index].subcommands.push_back(sub->get_name());
    collect_completion_paths(*sub, path.empty() ? sub->get_name() : path + " " + sub->get_name(),
                             out);
  }
}

std::string joined_words(const std::vector<std::string>& words) {
  std::string s;
  for (const auto& w : words) s += (s.empty() ? "" : " ") + w;
  return s;
}

// The body of _fleetgw: independent of the definitions, which it reads from the tables.
constexpr std::string_view kCompletionFunction = R"(_fleetgw() {
  local REPLY cur=${COMP_WORDS[COMP_CWORD]} path="" opt="" i w
  COMPREPLY=()
  # The command path and, when the word before the cursor is an option taking a value, that option.
  for ((i = 1; i < COMP_CWORD; i++)); do
    w=${COMP_WORDS[i]}
    if [[ -n $opt ]]; then
      [[ $w == "=" ]] && continue  # --opt=VALUE split at '=' (COMP_WORDBREAKS)
      opt=""
      continue
    fi
    if [[ $w == -* ]]; then
      [[ $w != *=* ]] && _fleetgw_value "$path" "$w" && opt=$w
      continue
    fi
    [[ -z $w ]] && continue
    _fleetgw_subcommands "$path"
    case " $REPLY " in *" $w "*) path=${path:+$path }$w ;; esac
  done
  if [[ -n $opt ]]; then
    [[ $cur == "=" ]] && cur=""
    _fleetgw_value "$path" "$opt"
    if [[ -n $REPLY ]]; then
      mapfile -t COMPREPLY < <(compgen -W "$REPLY" -- "$cur")
    else
      compopt -o filenames 2>/dev/null || true
      mapfile -t COMPREPLY < <(compgen -f -- "$cur")
    fi
    return 0
  fi
  if [[ $cur == --*=* ]]; then  # --opt=VALUE as one word ('=' not a word break)
    if _fleetgw_value "$path" "${cur%%=*}" && [[ -n $REPLY ]]; then
      mapfile -t COMPREPLY < <(compgen -P "${cur%%=*}=" -W "$REPLY" -- "${cur#*=}")
    fi
    return 0
  fi
  if [[ $cur != -* ]]; then
    _fleetgw_subcommands "$path"
    if [[ -n $REPLY ]]; then
      mapfile -t COMPREPLY < <(compgen -W "$REPLY" -- "$cur")
      return 0
    fi
    if _fleetgw_positional "$path"; then
      compopt -o filenames 2>/dev/null || true
      mapfile -t COMPREPLY < <(compgen -f -- "$cur")
      return 0
    fi
  fi
  _fleetgw_options "$path"
  mapfile -t COMPREPLY < <(compgen -W "$REPLY" -- "$cur")
  return 0
}
complete -F _fleetgw fleetgw
)";

}  // namespace

CLI::App* add_completion_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("completion", "print the bash completion script of fleetgw");
  cmd->group("");  // hidden: a packaging tool, not a command for the technician
  cmd->add_option("shell", "the shell (bash)")->required()->check(CLI::IsMember({"bash"}));
  return cmd;
}

void write_bash_completion(const CLI::App& app, std::ostream& out) {
  std::vector<CompletionPath> paths;
  collect_completion_paths(app, "", paths);
  out << "# bash completion for fleetgw " << FLEETGW_VERSION
      << ", generated by `fleetgw completion bash` from its\n"
         "# command-line definitions: regenerate it, do not edit it.\n\n"
         "# Tables: REPLY = the subcommands or options of a command path (\"\" for fleetgw, "
         "\"db rides\").\n";
  auto table = [&](const char* name, auto&& words_of) {
    out << "_fleetgw_" << name << "() {\n  case \"$1\" in\n";
    for (const auto& p : paths) {
      out << "    \"" << p.path << "\") REPLY=\"" << joined_words(words_of(p)) << "\" ;;\n";
    }
    out << "    *) REPLY=\"\" ;;\n  esac\n}\n";
  };
  table("subcommands", [](const CompletionPath& p) { return p.subcommands; });
  table("options", [](const CompletionPath& p) { return p.options; });
  out << "# Status 0 when option $2 of command path $1 takes a value; REPLY = the values CLI11\n"
         "# enumerates for it (empty: any value).\n"
         "_fleetgw_value() {\n  case \"$1 $2\" in\n";
  for (const auto& p : paths) {
    for (const auto& [name, values] : p.valued) {
      out << "    \"" << p.path << ' ' << name << "\") REPLY=\"" << joined_words(values)
          << "\" ;;\n";
    }
  }
  out << "    *) REPLY=\"\"; return 1 ;;\n  esac\n}\n"
         "# Status 0 when command path $1 takes positional arguments (file names are offered).\n"
         "_fleetgw_positional() {\n  case \"$1\" in\n";
  std::string positional;
  for (const auto& p : paths) {
    if (p.positional) positional += (positional.empty() ? "\"" : "|\"") + p.path + "\"";
  }
  if (!positional.empty()) out << "    " << positional << ") return 0 ;;\n";
  out << "  esac\n  return 1\n}\n\n" << kCompletionFunction;
}

}  // namespace fleetgw::cli
