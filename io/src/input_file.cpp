#include "input_file.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "citylod/io/file_check.hpp"

namespace citylod::io::detail {

InputFile::InputFile(const std::string& path, std::size_t buffer_size) : path_(path) {
  size_ = regular_file_size(path);  // a FIFO or a device would block or never end
  f_ = std::fopen(path.c_str(), "rb");
  if (!f_) throw IoError(path, std::string("cannot open: ") + std::strerror(errno));
  // no larger than the file: a small file does not pay for zeroing a large buffer
  buf_.resize(std::size_t(
      std::clamp<std::uint64_t>(size_ + 1, 4096, std::max<std::size_t>(buffer_size, 4096))));
}

InputFile::~InputFile() {
  if (f_) std::fclose(f_);
}

bool InputFile::fill() {
  // Keep unread bytes, move them to the front.
  if (pos_ < len_) {
    std::memmove(buf_.data(), buf_.data() + pos_, len_ - pos_);
    len_ -= pos_;
  } else {
    len_ = 0;
  }
  buf_pos_ += pos_;
  pos_ = 0;
  std::size_t got = std::fread(buf_.data() + len_, 1, buf_.size() - len_, f_);
  if (got == 0 && std::ferror(f_)) fail(std::string("read error: ") + std::strerror(errno));
  len_ += got;
  return got > 0;
}

void InputFile::seek(std::uint64_t offset) {
  if (offset >= buf_pos_ && offset <= buf_pos_ + len_) {
    pos_ = static_cast<std::size_t>(offset - buf_pos_);
    return;
  }
  if (offset > size_) fail("truncated: seek beyond the end of the file");
  if (fseeko(f_, static_cast<off_t>(offset), SEEK_SET) != 0) fail("seek failed");
  buf_pos_ = offset;
  pos_ = len_ = 0;
}

std::size_t InputFile::read_some(void* dst, std::size_t n) {
  char* out = static_cast<char*>(dst);
  std::size_t done = 0;
  while (done < n) {
    if (pos_ == len_) {
      // Large reads bypass the buffer.
      if (n - done >= buf_.size()) {
        buf_pos_ += len_;
        pos_ = len_ = 0;
        std::size_t got = std::fread(out + done, 1, n - done, f_);
        if (got == 0 && std::ferror(f_)) fail(std::string("read error: ") + std::strerror(errno));
        buf_pos_ += got;
        done += got;
        if (got == 0) break;
        continue;
      }
      if (!fill()) break;
    }
    std::size_t k = std::min(n - done, len_ - pos_);
    std::memcpy(out + done, buf_.data() + pos_, k);
    pos_ += k;
    done += k;
  }
  return done;
}

void InputFile::read_exact(void* dst, std::size_t n, const char* what) {
  if (read_some(dst, n) != n) fail(std::string("truncated: file ends inside ") + what);
}

int InputFile::peek() {
  if (pos_ == len_ && !fill()) return -1;
  return static_cast<unsigned char>(buf_[pos_]);
}

bool InputFile::getline(std::string& line, std::size_t max_len) {
  line.clear();
  bool any = false;
  for (;;) {
    if (pos_ == len_ && !fill()) return any;
    any = true;
    const char* begin = buf_.data() + pos_;
    const char* end = buf_.data() + len_;
    const char* nl = begin;
    while (nl != end && *nl != '\n' && *nl != '\r') ++nl;
    line.append(begin, nl);
    if (line.size() > max_len) fail("line too long (binary data in a text file?)");
    pos_ += static_cast<std::size_t>(nl - begin);
    if (nl != end) {
      char c = *nl;
      ++pos_;
      if (c == '\r' && peek() == '\n') ++pos_;
      return true;
    }
  }
}

std::size_t split_tokens(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0, n = line.size();
  while (i < n) {
    while (i < n && (is_space(line[i]) || line[i] == ',' || line[i] == ';')) ++i;
    if (i >= n) break;
    std::size_t j = i;
    while (j < n && !is_space(line[j]) && line[j] != ',' && line[j] != ';') ++j;
    out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out.size();
}

bool parse_double(std::string_view s, double& out) {
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  if (r.ec == std::errc::result_out_of_range) {
    // Denormals / huge values: fall back to strtod semantics (C locale digits only).
    std::string tmp(s);
    char* e = nullptr;
    out = std::strtod(tmp.c_str(), &e);
    return e == tmp.c_str() + tmp.size();
  }
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_u64(std::string_view s, std::uint64_t& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_i64(std::string_view s, std::int64_t& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::string check_finite(const double* p, std::uint64_t index) {
  for (int i = 0; i < 3; ++i) {
    if (std::isnan(p[i])) return "NaN coordinate at point #" + std::to_string(index);
    if (std::isinf(p[i])) return "infinite coordinate at point #" + std::to_string(index);
  }
  return {};
}

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace citylod::io::detail

namespace citylod::io {

std::string extension_of(const std::string& path) {
  auto slash = path.find_last_of('/');
  auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
  return detail::lower(path.substr(dot + 1));
}

}  // namespace citylod::io
