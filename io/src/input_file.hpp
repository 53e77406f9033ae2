// Private: a buffered, bounds-checked binary/text input file used by all readers.
#pragma once

#include <charconv>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "citylod/io/error.hpp"

namespace citylod::io::detail {

class InputFile {
 public:
  /// Opens for reading; throws IoError (missing file, directory, unreadable).
  explicit InputFile(const std::string& path, std::size_t buffer_size = 1 << 20);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  const std::string& path() const { return path_; }
  std::uint64_t size() const { return size_; }
  std::uint64_t tell() const { return buf_pos_ + pos_; }
  void seek(std::uint64_t offset);
  bool eof() const { return tell() >= size_; }

  /// Copies up to n bytes; returns how many were copied (< n only at end of file).
  std::size_t read_some(void* dst, std::size_t n);
  /// Reads exactly n bytes or throws IoError "truncated: <what>".
  void read_exact(void* dst, std::size_t n, const char* what);
  /// Next line without the terminator ('\n', "\r\n" or '\r'); false at end of file.
  /// Lines longer than max_len throw IoError.
  bool getline(std::string& line, std::size_t max_len = 1 << 20);
  /// Next byte or -1 at end of file (not consumed).
  int peek();

  [[noreturn]] void fail(const std::string& reason) const { throw IoError(path_, reason); }

 private:
  bool fill();  // refills the buffer; false at end of file

  std::string path_;
  std::FILE* f_ = nullptr;
  std::uint64_t size_ = 0;
  std::vector<char> buf_;
  std::uint64_t buf_pos_ = 0;  // file offset of buf_[0]
  std::size_t pos_ = 0;        // read position in buf_
  std::size_t len_ = 0;        // valid bytes in buf_
};

/// Splits a text line into tokens at whitespace and commas (no allocation:
/// views into `line`). Returns the number of tokens.
std::size_t split_tokens(std::string_view line, std::vector<std::string_view>& out);

/// Locale-independent number parsing of a whole token.
bool parse_double(std::string_view s, double& out);
bool parse_u64(std::string_view s, std::uint64_t& out);
bool parse_i64(std::string_view s, std::int64_t& out);

inline bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

/// Returns "NaN coordinate at point #k" / "infinite coordinate at point #k" or "".
std::string check_finite(const double* p, std::uint64_t index);

std::string lower(std::string s);

}  // namespace citylod::io::detail
