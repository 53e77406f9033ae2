// The command-line options of the three stages of a city run, declared and
// parsed in one place so that `citylod split`, `lod`,
// `assemble` and the one-command `citylod tile` share them.
//
//   declare_split_options(args);     // --crs, --origin, --footprints, --memory-limit, ...
//   declare_lod_param_options(args); // --set, --config
//   declare_assemble_options(args);  // --quantize, --max-triangles, ...
//   if (!args.parse()) return 0;
//   SplitOptions s = parse_split_options(args, inputs, work);  // force left to the caller
//   lod::LodParams p = parse_lod_params(args);        // --config then --set
//   AssembleParams a = parse_assemble_options(args);  // threads/force left to the caller
//
// Bad values throw UsageError (exit 2) naming the option.
#pragma once

#include <string>
#include <vector>

#include "citylod/lod/params.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/split.hpp"
#include "cli.hpp"

namespace citylod::app {

/// Everything of `citylod split` except --out and --force.
void declare_split_options(ArgParser& args);
/// Fills and validates a SplitOptions (force is left to the caller).
SplitOptions parse_split_options(const ArgParser& args, const std::vector<std::string>& inputs,
                                 const std::string& work_dir);

/// --set NAME=VALUE[,...] and --config FILE.
/// --set and --config, and the parameters' table for --help: `defaults` (the values
/// the command starts from) and, when the command also runs work directories, the
/// city values that differ (`city`).
void declare_lod_param_options(ArgParser& args, const lod::LodParams& defaults,
                               const lod::LodParams* city = nullptr);
/// `base` + --config + --set (not validated: the caller sets threads etc. first).
/// A bad --set throws UsageError; a bad --config file std::runtime_error.
lod::LodParams parse_lod_params(const ArgParser& args, lod::LodParams base = {});

/// --threads N (every command: 0 = all cores, the default). Returns N >= 0;
/// throws UsageError for a negative or non-numeric value.
void declare_threads_option(ArgParser& args, const std::string& what);
int parse_threads(const ArgParser& args);

/// Everything of `citylod assemble` except --out, --threads and --force.
void declare_assemble_options(ArgParser& args);
/// Fills an AssembleParams (not threads, force) and validates it.
AssembleParams parse_assemble_options(const ArgParser& args);

}  // namespace citylod::app
