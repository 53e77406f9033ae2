// The spelling of the library's options in messages (option_names.hpp).
#include "citylod/tiler/option_names.hpp"

namespace citylod::tiler {

namespace {
OptionSpelling g_spelling;
}  // namespace

void set_option_spelling(const OptionSpelling& s) {
  g_spelling = s;
}

std::string option_name(const std::string& field) {
  return g_spelling.option ? g_spelling.option(field) : field;
}

std::string rerun_name(const std::string& command, const std::string& field) {
  return g_spelling.rerun ? g_spelling.rerun(command, field) : command + " with " + field;
}

}  // namespace citylod::tiler
