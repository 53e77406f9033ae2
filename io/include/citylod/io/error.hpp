// The single error type of citylod::io.
#pragma once

#include <stdexcept>
#include <string>

namespace citylod::io {

/// Thrown by every reader and writer. what() is one line: "<file>: <reason>".
class IoError : public std::runtime_error {
 public:
  IoError(const std::string& file, const std::string& reason)
      : std::runtime_error(file + ": " + reason), file_(file), reason_(reason) {}
  /// For a message already formatted as "<file>: <reason>" (file() stays empty).
  explicit IoError(const std::string& message) : std::runtime_error(message), reason_(message) {}
  const std::string& file() const { return file_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string file_;
  std::string reason_;
};

}  // namespace citylod::io
