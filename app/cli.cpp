// citylod's command-line front end: global options, the subcommand table,
// the argument parser, logging, and the one place where exceptions become
// messages and exit codes (0 ok, 1 runtime failure, 2 usage error).
#include <algorithm>
#include <clocale>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>
#include <mutex>
#include <new>

#include "cli.hpp"

#ifndef CITYLOD_VERSION
#define CITYLOD_VERSION "unknown"
#endif

namespace citylod::app {

// ------------------------------------------------------------ subcommands
// To add a subcommand: write app/cmd_<name>.cpp defining
// `int cmd_<name>(ArgParser&)`, declare it here and add one row to kCommands.
int cmd_info(ArgParser& args);
int cmd_split(ArgParser& args);
int cmd_lod(ArgParser& args);
int cmd_assemble(ArgParser& args);
int cmd_serve(ArgParser& args);
int cmd_eval(ArgParser& args);
int cmd_tile(ArgParser& args);
int cmd_rebuild(ArgParser& args);
int cmd_cityjson(ArgParser& args);

namespace {

struct Command {
  const char* name;
  const char* summary;
  int (*run)(ArgParser&);
};

const Command kCommands[] = {
    {"info", "print format, counts, bounding box, attributes and CRS of point cloud / mesh files",
     cmd_info},
    {"split", "stream a georeferenced scene into per-building chunks (WORK/chunks, manifest.json)",
     cmd_split},
    {"lod",
     "build the LOD-Tree of one building: anchor and interpolation models (OBJ/PLY) + report",
     cmd_lod},
    {"assemble", "turn the per-building LOD models of a work directory into a 3D Tiles 1.1 tileset",
     cmd_assemble},
    {"tile",
     "one-command city run: split -> lod -> assemble, parallel, resumable (DIR/work, DIR/tileset)",
     cmd_tile},
    {"rebuild",
     "recompute one building of a 'tile' output (--set) or pin its models (--select), update the "
     "tileset",
     cmd_rebuild},
    {"cityjson",
     "write every building's LOD chain of a work directory as CityJSON 2.0 (CityJSONSeq)",
     cmd_cityjson},
    {"serve", "serve a tileset and the CesiumJS viewer on 127.0.0.1 (offline)", cmd_serve},
    {"eval", "validity, volume, e1/e2 RMSE and Hausdorff of models against their input", cmd_eval},
};

}  // namespace

// ------------------------------------------------------------ logging
namespace {
LogLevel g_level = LogLevel::info;
bool g_quiet = false;
std::mutex g_log_mutex;

void emit(const char* prefix, const std::string& msg) {
  std::lock_guard<std::mutex> lock(g_log_mutex);
  clear_progress_bar();
  std::fprintf(stderr, "citylod: %s%s\n", prefix, msg.c_str());
  std::fflush(stderr);
}

/// The sink of tiler::log_*(): --log-level and --quiet decide what is printed.
void stderr_sink(LogLevel level, const std::string& msg) {
  switch (level) {
    case LogLevel::error:
      emit("error: ", msg);
      break;
    case LogLevel::warn:
      if (g_level >= LogLevel::warn) emit("warning: ", msg);
      break;
    case LogLevel::info:
      if (g_level >= LogLevel::info && !g_quiet) emit("", msg);
      break;
    case LogLevel::debug:
      if (g_level >= LogLevel::debug) emit("debug: ", msg);
      break;
  }
}
}  // namespace

void install_log_sink() {
  set_log_sink(&stderr_sink);
}

namespace {
// The command line's names of the library's options (option_names.hpp): a
// field is its flag with '-' for '_', except where the flag says it otherwise.
std::string flag_of(const std::string& field) {
  if (field == "work_dir") return "--out";
  std::string f = field;
  std::replace(f.begin(), f.end(), '_', '-');
  return "--" + f;
}
std::string rerun_of(const std::string& command, const std::string& field) {
  return "citylod " + command + " " + flag_of(field);
}
}  // namespace

void install_option_spelling() {
  set_option_spelling({&flag_of, &rerun_of});
}

void set_log_level(LogLevel level) {
  g_level = level;
}
LogLevel log_level() {
  return g_level;
}
void set_quiet(bool q) {
  g_quiet = q;
}
bool quiet() {
  return g_quiet;
}

LogLevel parse_log_level(const std::string& s) {
  if (s == "error") return LogLevel::error;
  if (s == "warn" || s == "warning") return LogLevel::warn;
  if (s == "info") return LogLevel::info;
  if (s == "debug") return LogLevel::debug;
  throw UsageError("invalid log level '" + s + "' (expected error, warn, info or debug)");
}

// ------------------------------------------------------------ ArgParser
ArgParser::ArgParser(std::string command, std::vector<std::string> args)
    : command_(std::move(command)), args_(std::move(args)) {
  opts_.push_back({"help", 'h', false, "", "show this help and exit", ""});
  opts_.push_back({"log-level", 0, true, "LEVEL", "error, warn, info or debug", "info"});
  opts_.push_back({"quiet", 'q', false, "", "no progress display; only warnings and errors", ""});
}

ArgParser& ArgParser::usage(const std::string& s) {
  synopsis_ = s;
  return *this;
}
ArgParser& ArgParser::epilog(const std::string& s) {
  epilog_ = s;
  return *this;
}

ArgParser& ArgParser::describe(const std::string& s) {
  description_ = s;
  return *this;
}
ArgParser& ArgParser::flag(const std::string& name, char short_name, const std::string& help) {
  opts_.push_back({name, short_name, false, "", help, ""});
  return *this;
}
ArgParser& ArgParser::option(const std::string& name, char short_name, const std::string& metavar,
                             const std::string& help, const std::string& def) {
  opts_.push_back({name, short_name, true, metavar, help, def});
  return *this;
}
ArgParser& ArgParser::positional(const std::string& name, const std::string& help, Arity arity) {
  pos_.push_back({name, help, arity});
  return *this;
}

const ArgParser::Opt* ArgParser::find_long(const std::string& n) const {
  for (const auto& o : opts_)
    if (o.name == n) return &o;
  return nullptr;
}
const ArgParser::Opt* ArgParser::find_short(char c) const {
  for (const auto& o : opts_)
    if (o.short_name && o.short_name == c) return &o;
  return nullptr;
}
const ArgParser::Opt& ArgParser::declared(const std::string& name) const {
  const Opt* o = find_long(name);
  if (!o)
    throw std::logic_error("citylod " + command_ + ": option --" + name + " was never declared");
  return *o;
}

bool ArgParser::parse() {
  values_.clear();
  positionals_.clear();
  bool options_done = false;
  for (std::size_t i = 0; i < args_.size(); ++i) {
    const std::string& a = args_[i];
    if (options_done || a.size() < 2 || a[0] != '-') {
      positionals_.push_back(a);
      continue;
    }
    if (a == "--") {
      options_done = true;
      continue;
    }
    if (a[1] == '-') {
      std::string name = a.substr(2), value;
      bool inline_value = false;
      auto eq = name.find('=');
      if (eq != std::string::npos) {
        value = name.substr(eq + 1);
        name.resize(eq);
        inline_value = true;
      }
      const Opt* o = find_long(name);
      if (!o) throw UsageError("unknown option '--" + name + "' for 'citylod " + command_ + "'");
      if (o->takes_value) {
        if (!inline_value) {
          if (i + 1 >= args_.size())
            throw UsageError("option '--" + name + "' needs a value (" + o->metavar + ")");
          value = args_[++i];
        }
        values_[o->name] = value;
      } else {
        if (inline_value) throw UsageError("option '--" + name + "' takes no value");
        values_[o->name] = "1";
      }
      continue;
    }
    // Short options, possibly grouped: -qj, -oDIR, -o DIR.
    for (std::size_t k = 1; k < a.size(); ++k) {
      const Opt* o = find_short(a[k]);
      if (!o)
        throw UsageError(std::string("unknown option '-") + a[k] + "' for 'citylod " + command_ +
                         "'");
      if (!o->takes_value) {
        values_[o->name] = "1";
        continue;
      }
      std::string value = a.substr(k + 1);
      if (value.empty()) {
        if (i + 1 >= args_.size())
          throw UsageError(std::string("option '-") + a[k] + "' needs a value (" + o->metavar +
                           ")");
        value = args_[++i];
      }
      values_[o->name] = value;
      break;
    }
  }
  if (has("log-level")) set_log_level(parse_log_level(get("log-level")));
  if (has("quiet")) set_quiet(true);
  if (has("help")) {
    std::fputs(help_text().c_str(), stdout);
    return false;
  }
  // Positional counts.
  std::size_t min = 0, max = 0;
  bool unbounded = false;
  for (const auto& p : pos_) {
    switch (p.arity) {
      case Arity::none:
        break;
      case Arity::optional_one:
        max += 1;
        break;
      case Arity::one:
        min += 1;
        max += 1;
        break;
      case Arity::zero_or_more:
        unbounded = true;
        break;
      case Arity::one_or_more:
        min += 1;
        unbounded = true;
        break;
    }
  }
  if (positionals_.size() < min) {
    std::string names;
    for (const auto& p : pos_)
      if (p.arity == Arity::one || p.arity == Arity::one_or_more)
        names += (names.empty() ? "" : " ") + p.name;
    throw UsageError("missing argument " + names);
  }
  if (!unbounded && positionals_.size() > max)
    throw UsageError("unexpected argument '" + positionals_[max] + "'");
  return true;
}

bool ArgParser::has(const std::string& name) const {
  declared(name);
  return values_.count(name) > 0;
}

std::string ArgParser::get(const std::string& name) const {
  const Opt& o = declared(name);
  auto it = values_.find(name);
  return it != values_.end() ? it->second : o.def;
}

double ArgParser::get_double(const std::string& name) const {
  std::string v = get(name);
  char* end = nullptr;
  double d = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0')
    throw UsageError("option '--" + name + "' expects a number, got '" + v + "'");
  return d;
}

std::int64_t ArgParser::get_int(const std::string& name) const {
  std::string v = get(name);
  char* end = nullptr;
  long long d = std::strtoll(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0')
    throw UsageError("option '--" + name + "' expects an integer, got '" + v + "'");
  return d;
}

std::string ArgParser::help_text() const {
  std::string s = "usage: citylod " + command_ + " [options]" +
                  (synopsis_.empty() ? "" : " " + synopsis_) + "\n";
  if (!description_.empty()) s += "\n" + description_ + "\n";
  auto row = [](std::string left, const std::string& help) {
    if (left.size() < 28)
      left.resize(28, ' ');
    else
      left += "\n" + std::string(28, ' ');
    return "  " + left + help + "\n";
  };
  if (!pos_.empty()) {
    s += "\narguments:\n";
    for (const auto& p : pos_) s += row(p.name, p.help);
  }
  s += "\noptions:\n";
  // Command options first, then the global ones.
  for (int pass = 0; pass < 2; ++pass)
    for (std::size_t i = 0; i < opts_.size(); ++i) {
      if ((i < 3) != (pass == 1)) continue;
      const Opt& o = opts_[i];
      std::string left = o.short_name ? std::string("-") + o.short_name + ", " : "    ";
      left += "--" + o.name + (o.takes_value ? " " + o.metavar : "");
      std::string help = o.help;
      if (!o.def.empty()) help += " (default: " + o.def + ")";
      s += row(left, help);
    }
  if (!epilog_.empty()) s += "\n" + epilog_;
  return s;
}

// ------------------------------------------------------------ run_cli
namespace {

std::string one_line(std::string s) {
  for (auto& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

std::string top_help() {
  std::string s =
      "usage: citylod [--log-level LEVEL] [--quiet] <command> [options] [args]\n"
      "\nTurns georeferenced urban scenes (meshes, LiDAR point clouds) into 3D Tiles.\n"
      "\ncommands:\n";
  for (const auto& c : kCommands) {
    std::string n = c.name;
    n.resize(std::max<std::size_t>(n.size(), 12), ' ');
    s += "  " + n + c.summary + "\n";
  }
  s += "\nglobal options:\n"
       "  -h, --help                  show this help (or 'citylod <command> --help')\n"
       "  -V, --version               print the version\n"
       "      --log-level LEVEL       error, warn, info or debug (default: info)\n"
       "  -q, --quiet                 no progress display; only warnings and errors\n";
  return s;
}

int usage_error(const std::string& msg, const std::string& cmd) {
  std::fprintf(stderr, "citylod: error: %s\nsee 'citylod%s --help'\n", one_line(msg).c_str(),
               cmd.empty() ? "" : (" " + cmd).c_str());
  return 2;
}

}  // namespace

int run_cli(int argc, char** argv) {
  std::setlocale(LC_ALL, "C");
  install_log_sink();
  install_option_spelling();
  std::vector<std::string> args(argv + 1, argv + argc);
  std::string cmd_name;
  std::unique_ptr<ArgParser> parser;  // outlives the command: an error names its inputs
  try {
    std::size_t i = 0;
    for (; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a == "--help" || a == "-h") {
        std::fputs(top_help().c_str(), stdout);
        return 0;
      }
      if (a == "--version" || a == "-V") {
        std::printf("citylod %s\n", CITYLOD_VERSION);
        return 0;
      }
      if (a == "--quiet" || a == "-q") {
        set_quiet(true);
      } else if (a == "--log-level") {
        if (i + 1 >= args.size()) throw UsageError("option '--log-level' needs a value (LEVEL)");
        set_log_level(parse_log_level(args[++i]));
      } else if (a.rfind("--log-level=", 0) == 0) {
        set_log_level(parse_log_level(a.substr(12)));
      } else if (!a.empty() && a[0] == '-') {
        throw UsageError("unknown option '" + a + "'");
      } else {
        break;
      }
    }
    if (i >= args.size()) {
      std::fputs(top_help().c_str(), stderr);
      return 2;
    }
    const Command* cmd = nullptr;
    for (const auto& c : kCommands)
      if (args[i] == c.name) cmd = &c;
    if (!cmd) throw UsageError("unknown command '" + args[i] + "'");
    cmd_name = cmd->name;
    parser = std::make_unique<ArgParser>(
        cmd->name, std::vector<std::string>(args.begin() + static_cast<long>(i) + 1, args.end()));
    return cmd->run(*parser);
  } catch (const UsageError& e) {
    return usage_error(e.what(), cmd_name);
  } catch (const Cancelled&) {
    log_error("cancelled");
    return 1;
  } catch (const std::bad_alloc&) {
    // the one error without a file of its own: name what the command was working
    // on, its positional arguments (the inputs), not the option values
    std::string subject;
    for (const std::string& a : parser ? parser->positionals() : std::vector<std::string>{})
      if (subject.size() < 200) subject += (subject.empty() ? "" : ", ") + a;
    log_error((subject.empty() ? cmd_name : cmd_name + " " + subject) +
              ": out of memory (the input needs more memory than this machine has, or declares "
              "sizes it does not hold)");
    return 1;
  } catch (const std::exception& e) {
    log_error(one_line(e.what()));
    return 1;
  } catch (...) {
    log_error("unknown exception");
    return 1;
  }
}

}  // namespace citylod::app
