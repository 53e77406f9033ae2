// How the library's messages and notes name its options. The library knows an
// option by its field name (SplitOptions::memory_limit is "memory_limit",
// SplitOptions::seg.cluster_tolerance is "cluster_tolerance") and never spells
// a command-line flag; a program that offers the options under names of its
// own installs its spelling once, before any work starts (the citylod CLI:
// "--memory-limit", "citylod split --force"; app/cli.cpp).
#pragma once

#include <string>

namespace citylod::tiler {

struct OptionSpelling {
  /// An option by its field name: "memory_limit" -> e.g. "--memory-limit".
  std::string (*option)(const std::string& field) = nullptr;
  /// A command run again with one of its options: ("split", "force") -> e.g.
  /// "citylod split --force".
  std::string (*rerun)(const std::string& command, const std::string& field) = nullptr;
};

/// Installs `s` (a null member keeps the library's own spelling). Not
/// thread-safe: call it before any work starts.
void set_option_spelling(const OptionSpelling& s);

/// The option `field` as messages name it: the installed spelling, else the field name.
std::string option_name(const std::string& field);
/// `command` run with `field`: the installed spelling, else "<command> with <field>".
std::string rerun_name(const std::string& command, const std::string& field);

}  // namespace citylod::tiler
