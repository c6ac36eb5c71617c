// `fleetgw completion bash`: the bash completion script of fleetgw, generated at run time from
// the CLI11 definitions of the running binary, so it cannot disagree with them. The Debian
// package installs its output as /usr/share/bash-completion/completions/fleetgw (generated at
// build time, deploy/packaging.cmake).
//
// Contract:
//  * write_bash_completion(app, out) walks `app` and its visible subcommands, recursively (a
//    hidden subcommand, in CLI11's group "", is left out: `completion` itself); for each command
//    path ("", "decode", "db rides", ...) it writes its subcommands, its options' long and short
//    names (--help and --version included, hidden options left out), which of those options
//    take a value, the values CLI11 enumerates for them (IsMember and transformer sets, e.g.
//    `--crc-order` be le auto; ranges and free values enumerate nothing) and whether the path
//    takes positional arguments. A name or value with a character outside [A-Za-z0-9_.,:+@%/-]
//    is left out: every word is literal in a bash `case` pattern and a `compgen -W` list.
//  * The script is plain bash (no bash-completion helpers, so it can be sourced on its own and
//    tested by setting COMP_WORDS/COMP_CWORD): it defines _fleetgw and registers it with
//    `complete -F _fleetgw fleetgw`. _fleetgw sets COMPREPLY to: after an option that takes a
//    value (`--opt VALUE`, `--opt=VALUE`), that option's enumerated values, or file names when
//    it has none; for a word starting with "-", the options of the current command path;
//    otherwise the subcommands of the current path, or file names when it has none but takes
//    positional arguments, or else its options.
#pragma once

#include <CLI/CLI.hpp>

#include <ostream>

namespace fleetgw::cli {

// Adds the hidden `completion SHELL` subcommand (SHELL: bash) to `app` and returns it: when it
// was parsed, the caller prints write_bash_completion(app, ...) once everything is registered.
CLI::App* add_completion_command(CLI::App& app);

void write_bash_completion(const CLI::App& app, std::ostream& out);

}  // namespace fleetgw::cli
