// Reading a JSON file with the one error policy of citylod::io.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace citylod::io {

/// Parses the file; throws IoError("<path>: no such file" | "is not a regular file ..." |
/// "larger than 256 MiB ..." | "cannot open" | "not valid JSON (<parser message on one line>)").
nlohmann::json read_json_file(const std::string& path);

}  // namespace citylod::io
