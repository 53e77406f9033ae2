// What a subcommand (app/cmd_<name>.cpp) needs: the argument parser, the
// log level, the progress display and the usage-error type.
//
// A subcommand is a function `int cmd_<name>(ArgParser& args)`:
//
//   int cmd_info(ArgParser& args) {
//     args.usage("FILE...").describe("Print what a point cloud or mesh file holds.");
//     args.flag("json", 'j', "print JSON instead of text");
//     args.positional("FILE", "input file(s)", Arity::one_or_more);
//     if (!args.parse()) return 0;          // --help was printed
//     ... ONE library call (citylod::tiler), then print its result
//     return 0;
//   }
//
// and one row in the command table of cli.cpp. Exceptions propagate to
// run_cli(), which prints "citylod: error: <what()>" and returns 1
// (UsageError: the message plus "see 'citylod <cmd> --help'", exit 2).
// Library messages (tiler::log_*) reach stderr through the sink cli.cpp sets.
#pragma once

#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "citylod/tiler/log.hpp"
#include "citylod/tiler/option_names.hpp"
#include "progress_bar.hpp"

namespace citylod::app {

using namespace citylod::tiler;

/// printf into a std::string.
inline std::string strf(const char* f, ...) __attribute__((format(printf, 1, 2)));
inline std::string strf(const char* f, ...) {
  va_list a, b;
  va_start(a, f);
  va_copy(b, a);
  const int n = std::vsnprintf(nullptr, 0, f, a);
  va_end(a);
  std::string s(n > 0 ? std::size_t(n) : 0, '\0');
  if (n > 0) std::vsnprintf(s.data(), s.size() + 1, f, b);
  va_end(b);
  return s;
}

/// The command line, from main(): 0 ok, 1 runtime failure, 2 usage error.
int run_cli(int argc, char** argv);

/// Bad command line: exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Runs `f`; a std::invalid_argument it throws (a bad option value refused
/// by the library) becomes a UsageError (exit 2).
template <class F>
auto usage_errors(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

// ---------------------------------------------------------------- logging
// The sink (cli.cpp) prints tiler::log_*() messages on stderr as
// "citylod: [<level>: ]<message>", filtered by these settings.
void set_log_level(LogLevel level);
LogLevel log_level();
/// --quiet: no progress display, only warnings and errors.
void set_quiet(bool quiet);
bool quiet();
/// Parses "error|warn|info|debug"; throws UsageError otherwise.
LogLevel parse_log_level(const std::string& s);

/// Installs the stderr sink (thread-safe; clears a progress bar first).
void install_log_sink();
/// Messages of the library name its options by their flags (option_names.hpp).
void install_option_spelling();

// ---------------------------------------------------------------- arguments
enum class Arity { none, optional_one, one, zero_or_more, one_or_more };

/// GNU-style option parser for one subcommand: --name VALUE, --name=VALUE,
/// -n VALUE, -nVALUE, grouped short flags (-qv), "--" ends options. The
/// global options --log-level LEVEL, --quiet/-q and --help/-h are always
/// accepted (also after the subcommand).
class ArgParser {
 public:
  /// `command` is the subcommand name ("info"); `args` are the words after it.
  ArgParser(std::string command, std::vector<std::string> args);

  ArgParser& usage(const std::string& positional_synopsis);  ///< e.g. "FILE..."
  ArgParser& describe(const std::string& text);              ///< shown under the usage line
  /// Text printed after the options in --help (e.g. a table of parameters).
  ArgParser& epilog(const std::string& s);
  /// A boolean switch.
  ArgParser& flag(const std::string& name, char short_name, const std::string& help);
  /// An option with a value; `def` is shown in --help and returned by get() when absent.
  ArgParser& option(const std::string& name, char short_name, const std::string& metavar,
                    const std::string& help, const std::string& def = "");
  /// Documents positional arguments (for --help and count checks).
  ArgParser& positional(const std::string& name, const std::string& help, Arity arity);

  /// Parses; returns false if --help was printed (the command should return 0).
  /// Throws UsageError on unknown options, missing values, wrong positional count.
  bool parse();

  bool has(const std::string& name) const;  ///< flag set, or option given
  std::string get(const std::string& name) const;
  double get_double(const std::string& name) const;  ///< throws UsageError if not a number
  std::int64_t get_int(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return positionals_; }

  const std::string& command() const { return command_; }
  std::string help_text() const;

 private:
  struct Opt {
    std::string name;
    char short_name = 0;
    bool takes_value = false;
    std::string metavar, help, def;
  };
  struct Pos {
    std::string name, help;
    Arity arity;
  };
  const Opt* find_long(const std::string& n) const;
  const Opt* find_short(char c) const;
  const Opt& declared(const std::string& name) const;

  std::string command_;
  std::vector<std::string> args_;
  std::string synopsis_, description_, epilog_;
  std::vector<Opt> opts_;
  std::vector<Pos> pos_;
  std::map<std::string, std::string> values_;
  std::vector<std::string> positionals_;
};

}  // namespace citylod::app
