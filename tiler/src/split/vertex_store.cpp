// VertexStore: a mesh file's vertices in memory or paged from a file (vertex_store.hpp).
#include "vertex_store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "citylod/io/error.hpp"

namespace citylod::tiler {

namespace {

template <typename T>
void put(char*& p, const T& v) {
  std::memcpy(p, &v, sizeof(T));
  p += sizeof(T);
}
template <typename T>
void take(const char*& p, T& v) {
  std::memcpy(&v, p, sizeof(T));
  p += sizeof(T);
}

}  // namespace

VertexStore::VertexStore(Layout layout, std::uint64_t count, std::uint64_t budget, std::string path)
    : layout_(layout), path_(std::move(path)) {
  rec_ = sizeof(io::Vec3d) + (layout.file ? sizeof(io::Vec3d) : 0) +
         (layout.normals ? sizeof(io::Vec3f) : 0) + (layout.colors ? sizeof(io::Rgb8) : 0);
  if (double(count) * double(rec_) <= double(budget)) {
    pos_.reserve(count);
    if (layout.file) file_.reserve(count);
    if (layout.normals) normals_.reserve(count);
    if (layout.colors) colors_.reserve(count);
    return;
  }
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd_ < 0) throw io::IoError(path_, std::string("cannot create: ") + std::strerror(errno));
  const std::uint64_t block_bytes = kBlock * rec_;
  slots_.resize(std::size_t(std::max<std::uint64_t>(2, budget / block_bytes)));
  out_.reserve(std::size_t(block_bytes));
}

VertexStore::~VertexStore() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
}

void VertexStore::append(const io::Vec3d* pos, const io::Vec3d* file, const io::Vec3f* normals,
                         const io::Rgb8* colors, std::size_t n) {
  size_ += n;
  if (fd_ < 0) {
    pos_.insert(pos_.end(), pos, pos + n);
    if (layout_.file) {
      if (file)
        file_.insert(file_.end(), file, file + n);
      else
        file_.resize(file_.size() + n, io::Vec3d{});
    }
    if (layout_.normals) {
      if (normals)
        normals_.insert(normals_.end(), normals, normals + n);
      else
        normals_.resize(normals_.size() + n, io::Vec3f{});
    }
    if (layout_.colors) {
      if (colors)
        colors_.insert(colors_.end(), colors, colors + n);
      else
        colors_.resize(colors_.size() + n, io::Rgb8{});
    }
    return;
  }
  const io::Vec3d zero3d{};
  const io::Vec3f zero3f{};
  const io::Rgb8 zero_rgb{};
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t at = out_.size();
    out_.resize(at + rec_);
    char* p = out_.data() + at;
    put(p, pos[k]);
    if (layout_.file) put(p, file ? file[k] : zero3d);
    if (layout_.normals) put(p, normals ? normals[k] : zero3f);
    if (layout_.colors) put(p, colors ? colors[k] : zero_rgb);
    if (out_.size() >= kBlock * rec_) flush();
  }
}

void VertexStore::flush() {
  if (fd_ < 0 || out_.empty()) return;
  const char* p = out_.data();
  std::size_t left = out_.size();
  off_t at = off_t(written_ * rec_);
  while (left > 0) {
    const ssize_t w = ::pwrite(fd_, p, left, at);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) throw io::IoError(path_, std::string("cannot write: ") + std::strerror(errno));
    p += w;
    at += w;
    left -= std::size_t(w);
  }
  written_ += out_.size() / rec_;
  out_.clear();
}

void VertexStore::read_block(std::uint64_t block, std::vector<char>& out) const {
  const std::uint64_t first = block * kBlock;
  const std::uint64_t n = std::min<std::uint64_t>(kBlock, written_ - first);
  out.resize(std::size_t(n * rec_));
  char* p = out.data();
  std::size_t left = out.size();
  off_t at = off_t(first * rec_);
  while (left > 0) {
    const ssize_t r = ::pread(fd_, p, left, at);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) throw io::IoError(path_, "cannot read back the vertices (file shortened?)");
    p += r;
    at += r;
    left -= std::size_t(r);
  }
}

VertexStore::Vertex VertexStore::get(std::uint32_t i) const {
  Vertex v;
  if (fd_ < 0) {
    v.pos = pos_[i];
    if (layout_.file) v.file = file_[i];
    if (layout_.normals) v.normal = normals_[i];
    if (layout_.colors) v.color = colors_[i];
    return v;
  }
  const std::uint64_t block = i / kBlock;
  Slot& s = slots_[std::size_t(block % slots_.size())];
  if (s.block != std::int64_t(block)) {
    read_block(block, s.data);
    s.block = std::int64_t(block);
  }
  const char* p = s.data.data() + std::size_t((i % kBlock) * rec_);
  take(p, v.pos);
  if (layout_.file) take(p, v.file);
  if (layout_.normals) take(p, v.normal);
  if (layout_.colors) take(p, v.color);
  return v;
}

}  // namespace citylod::tiler
