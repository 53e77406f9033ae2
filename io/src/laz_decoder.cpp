// LAZ point data: the laszip VLR, the chunk table and chunk-by-chunk decoding
// (sequential, or a few chunks ahead on worker threads).
//
// Layout: at the point data offset an int64 gives the position of the chunk
// table (-1: the position is in the last 8 bytes of the file); the chunks
// follow. The table is {u32 version = 0, u32 chunk count} and, arithmetic
// coded, per chunk its point count (variable chunk size only) and its byte
// size, each predicted from the previous chunk's.
#include "laz_decoder.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <thread>

#include "citylod/io/error.hpp"
#include "input_file.hpp"
#include "laz_chunk.hpp"

namespace citylod::io::detail {

using laz::ByteSource;
using laz::CorruptData;
using laz::Item;

namespace {

template <typename T>
T le(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

constexpr std::uint32_t kVariableChunks = 0xFFFFFFFFu;
constexpr std::uint64_t kMaxChunks = 1u << 24;
constexpr std::uint64_t kMaxParallelChunkBytes = 64u << 20;  // decoded records per chunk

struct Chunk {
  std::uint64_t offset = 0;
  std::uint64_t first_point = 0;
  std::uint32_t bytes = 0;
  std::uint32_t points = 0;
};

}  // namespace

namespace laz {
std::string item_name(const Item& it) {
  const char* n = "unknown";
  switch (it.type) {
    case kByte:
      n = "BYTE";
      break;
    case 1:
      n = "SHORT";
      break;
    case 2:
      n = "INT";
      break;
    case 3:
      n = "LONG";
      break;
    case 4:
      n = "FLOAT";
      break;
    case 5:
      n = "DOUBLE";
      break;
    case kPoint10:
      n = "POINT10";
      break;
    case kGpsTime11:
      n = "GPSTIME11";
      break;
    case kRgb12:
      n = "RGB12";
      break;
    case kWavepacket13:
      n = "WAVEPACKET13";
      break;
    case kPoint14:
      n = "POINT14";
      break;
    case kRgb14:
      n = "RGB14";
      break;
    case kRgbNir14:
      n = "RGBNIR14";
      break;
    case kWavepacket14:
      n = "WAVEPACKET14";
      break;
    case kByte14:
      n = "BYTE14";
      break;
    default:
      break;
  }
  return std::string(n) + " v" + std::to_string(it.version);
}
}  // namespace laz

int default_laz_threads() {
  if (const char* e = std::getenv("CITYLOD_LAZ_THREADS")) {
    const int v = std::atoi(e);
    if (v >= 1) return std::min(v, 64);
  }
  const unsigned hw = std::thread::hardware_concurrency();
  return static_cast<int>(std::max(1u, std::min(hw, 4u)));
}

struct LazStream::Impl {
  LazSource src;
  InputFile file;
  std::uint16_t compressor = 0;
  std::uint32_t chunk_size = 0;
  std::string version;
  std::vector<Item> items;
  std::vector<Chunk> chunks;
  std::mutex file_mutex;

  // sequential state
  std::size_t next_chunk = 0;  // chunk to start next
  std::size_t cur = 0;         // chunk being decoded (valid when left > 0)
  std::uint64_t left = 0;      // points left in chunk `cur`
  std::vector<unsigned char> bytes;
  std::unique_ptr<laz::ChunkDecoder> decoder;

  // parallel state
  int threads = 1;
  std::vector<std::thread> workers;
  std::mutex m;
  std::condition_variable cv;
  bool stop = false;
  std::size_t next_job = 0;
  std::size_t window_end = 0;  // chunks < window_end may be decoded ahead
  struct Result {
    std::vector<unsigned char> records;
    std::string error;
  };
  std::map<std::size_t, Result> results;
  Result current;  // records of chunk `cur` (parallel mode)
  std::size_t current_pos = 0;

  explicit Impl(const LazSource& s) : src(s), file(s.path) {}

  [[noreturn]] void fail(const std::string& reason) const { throw IoError(src.path, reason); }

  void parse_vlr() {
    const auto& v = src.vlr;
    if (v.size() < 34) fail("bad LAZ: the laszip VLR is " + std::to_string(v.size()) + " bytes");
    compressor = le<std::uint16_t>(v.data());
    const std::uint16_t coder = le<std::uint16_t>(v.data() + 2);
    version = std::to_string(v[4]) + "." + std::to_string(v[5]) + "r" +
              std::to_string(le<std::uint16_t>(v.data() + 6));
    chunk_size = le<std::uint32_t>(v.data() + 12);
    const std::uint16_t n_items = le<std::uint16_t>(v.data() + 32);
    if (v.size() < 34 + 6u * n_items)
      fail("bad LAZ: the laszip VLR lists " + std::to_string(n_items) + " items but holds " +
           std::to_string((v.size() - 34) / 6));
    if (coder != 0) fail("unsupported LAZ coder " + std::to_string(coder));
    std::uint32_t total = 0;
    for (std::uint16_t i = 0; i < n_items; ++i) {
      Item it;
      it.type = le<std::uint16_t>(v.data() + 34 + 6 * i);
      it.size = le<std::uint16_t>(v.data() + 36 + 6 * i);
      it.version = le<std::uint16_t>(v.data() + 38 + 6 * i);
      items.push_back(it);
      total += it.size;
    }
    if (compressor == 0) fail("bad LAZ: the laszip VLR says the points are not compressed");
    if (compressor == 1)
      fail(
          "unsupported LAZ: unchunked point-wise compression (LASzip 1.x); recompress with "
          "'laszip' or 'pdal translate'");
    if (compressor != 2 && compressor != 3)
      fail("unsupported LAZ compressor " + std::to_string(compressor));
    if (total != src.record_length)
      fail("bad LAZ: the laszip items make " + std::to_string(total) +
           "-byte records but the header declares " + std::to_string(src.record_length));
    if (items.empty()) fail("bad LAZ: the laszip VLR lists no items");
    for (std::size_t i = 0; i < items.size(); ++i) {
      const Item& it = items[i];
      const std::string name = laz::item_name(it);
      bool ok = false;
      if (compressor == 2) {
        ok = it.version == 2 &&
             ((it.type == laz::kPoint10 && it.size == 20 && i == 0) ||
              (it.type == laz::kGpsTime11 && it.size == 8) ||
              (it.type == laz::kRgb12 && it.size == 6) || (it.type == laz::kByte && it.size > 0));
        // waveform packets (formats 4, 5) have only the version-1 coder
        if (it.type == laz::kWavepacket13) ok = it.version == 1 && it.size == 29;
        if (!ok && it.version == 1 && it.type != laz::kWavepacket13)
          fail("unsupported LAZ item " + name +
               " (LASzip 1.x compression); recompress with "
               "'laszip' or 'pdal translate'");
      } else {
        ok = (it.version == 3 || it.version == 4) &&
             ((it.type == laz::kPoint14 && it.size == 30 && i == 0) ||
              (it.type == laz::kRgb14 && it.size == 6) ||
              (it.type == laz::kRgbNir14 && it.size == 8) ||
              (it.type == laz::kWavepacket14 && it.size == 29) ||
              (it.type == laz::kByte14 && it.size > 0 && i + 1 == items.size()));
      }
      if (!ok)
        fail("unsupported LAZ item " + name + " of size " + std::to_string(it.size) + " for " +
             (compressor == 2 ? "point-wise" : "layered") + " compression");
    }
    if (chunk_size == 0) fail("bad LAZ: chunk size 0 in the laszip VLR");
  }

  void read_chunk_table() {
    const std::uint64_t start = src.point_offset + 8;  // first chunk
    if (src.point_count == 0) return;
    if (start > src.data_end) fail("truncated LAZ: no chunk table offset after the header");
    unsigned char b[8];
    file.seek(src.point_offset);
    file.read_exact(b, 8, "the LAZ chunk table offset");
    std::int64_t table = le<std::int64_t>(b);
    if (table == -1) {  // written at the end of the file
      if (src.file_size < 8) fail("truncated LAZ file");
      file.seek(src.file_size - 8);
      file.read_exact(b, 8, "the LAZ chunk table offset");
      table = le<std::int64_t>(b);
    }
    if (table == static_cast<std::int64_t>(src.point_offset))
      fail("bad LAZ: the chunk table is missing (the compressor was interrupted?)");
    if (table < static_cast<std::int64_t>(start) ||
        static_cast<std::uint64_t>(table) + 8 > src.file_size)
      fail("bad LAZ: the chunk table offset " + std::to_string(table) + " lies outside the file (" +
           std::to_string(src.file_size) + " bytes): truncated?");
    const std::uint64_t table_pos = static_cast<std::uint64_t>(table);
    file.seek(table_pos);
    file.read_exact(b, 8, "the LAZ chunk table");
    const std::uint32_t version = le<std::uint32_t>(b), n = le<std::uint32_t>(b + 4);
    if (version != 0) fail("bad LAZ: chunk table version " + std::to_string(version));
    const std::uint64_t area = table_pos - start;  // bytes of all chunks
    const bool variable = chunk_size == kVariableChunks;
    std::uint64_t expected = 0;
    if (!variable) expected = (src.point_count + chunk_size - 1) / chunk_size;
    if (n == 0) fail("bad LAZ: the chunk table lists no chunks");
    if (!variable && n != expected)
      fail("bad LAZ: the chunk table lists " + std::to_string(n) + " chunks but " +
           std::to_string(src.point_count) + " points in chunks of " + std::to_string(chunk_size) +
           " need " + std::to_string(expected));
    if (n > kMaxChunks || n > src.point_count ||
        n > area / std::max<std::uint32_t>(1, src.record_length))
      fail("bad LAZ: the chunk table lists " + std::to_string(n) + " chunks for " +
           std::to_string(src.point_count) + " points in " + std::to_string(area) + " bytes");
    // The compressed entries: at most ~10 bytes per value; bounded by the file.
    const std::uint64_t avail = src.file_size - table_pos - 8;
    const std::uint64_t want = std::min<std::uint64_t>(avail, 64 + 24ull * n);
    std::vector<unsigned char> t(static_cast<std::size_t>(want));
    file.read_exact(t.data(), t.size(), "the LAZ chunk table");
    chunks.resize(n);
    try {
      ByteSource bs(t.data(), t.size());
      laz::ArithmeticDecoder dec;
      dec.init(bs);
      laz::IntegerDecompressor ic(32, 2);
      std::uint32_t prev_points = 0, prev_bytes = 0;
      for (std::uint32_t i = 0; i < n; ++i) {
        if (variable) {
          prev_points = static_cast<std::uint32_t>(
              ic.decompress(dec, static_cast<std::int32_t>(prev_points), 0));
          chunks[i].points = prev_points;
        }
        prev_bytes = static_cast<std::uint32_t>(
            ic.decompress(dec, static_cast<std::int32_t>(prev_bytes), 1));
        chunks[i].bytes = prev_bytes;
      }
      if (dec.overrun()) throw CorruptData("compressed data ends early");
    } catch (const CorruptData& e) {
      fail(std::string("corrupt LAZ chunk table: ") + e.what());
    }
    std::uint64_t off = start, first = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      Chunk& c = chunks[i];
      if (!variable)
        c.points = static_cast<std::uint32_t>(
            std::min<std::uint64_t>(chunk_size, src.point_count - first));
      const std::string which = "chunk " + std::to_string(i) + " of " + std::to_string(n);
      if (c.points == 0) fail("bad LAZ chunk table: " + which + " holds no points");
      if (c.bytes == 0 || c.bytes > table_pos - off)
        fail("bad LAZ chunk table: " + which + " (" + std::to_string(c.bytes) +
             " bytes at offset " + std::to_string(off) +
             ") extends beyond the chunk data, which ends at " + std::to_string(table_pos) +
             " (truncated or corrupt file)");
      if (first + c.points > src.point_count)
        fail("bad LAZ chunk table: the chunks hold more points than the " +
             std::to_string(src.point_count) + " of the header");
      c.offset = off;
      c.first_point = first;
      off += c.bytes;
      first += c.points;
    }
    if (first != src.point_count)
      fail("bad LAZ chunk table: the chunks hold " + std::to_string(first) +
           " points but the header declares " + std::to_string(src.point_count));
  }

  std::string chunk_name(std::size_t i) const {
    const Chunk& c = chunks[i];
    return "chunk " + std::to_string(i) + " of " + std::to_string(chunks.size()) + " (points " +
           std::to_string(c.first_point) + "-" + std::to_string(c.first_point + c.points - 1) +
           ", " + std::to_string(c.bytes) + " bytes at offset " + std::to_string(c.offset) + ")";
  }

  std::string corrupt_message(std::size_t i, const std::string& why) const {
    return src.path + ": corrupt LAZ data in " + chunk_name(i) + ": " + why;
  }

  void load_bytes(std::size_t i, std::vector<unsigned char>& out) {
    const Chunk& c = chunks[i];
    out.resize(c.bytes);
    std::lock_guard<std::mutex> lock(file_mutex);
    file.seek(c.offset);
    if (file.read_some(out.data(), out.size()) != out.size())
      throw IoError(corrupt_message(i, "the file ends inside the chunk (truncated)"));
  }

  std::unique_ptr<laz::ChunkDecoder> make_decoder(std::size_t i,
                                                  const std::vector<unsigned char>& data) {
    ByteSource bs(data.data(), data.size());
    if (compressor == 2) return laz::make_pointwise_decoder(items, bs);
    return laz::make_layered_decoder(items, bs, chunks[i].points);
  }

  // ---- sequential ----
  std::size_t read_sequential(unsigned char* dst, std::size_t n) {
    std::size_t done = 0;
    const std::size_t rl = src.record_length;
    while (done < n) {
      if (left == 0) {
        if (next_chunk >= chunks.size()) break;
        cur = next_chunk++;
        load_bytes(cur, bytes);
        decoder = make_decoder(cur, bytes);
        left = chunks[cur].points;
      }
      const std::size_t k = static_cast<std::size_t>(std::min<std::uint64_t>(left, n - done));
      try {
        decoder->decode(dst + done * rl, k);
        left -= k;
        if (left == 0) decoder->finish();
      } catch (const CorruptData& e) {
        left = 0;
        next_chunk = chunks.size();
        throw IoError(corrupt_message(cur, e.what()));
      }
      done += k;
    }
    return done;
  }

  // ---- parallel ----
  void start_workers() {
    window_end = std::min<std::size_t>(chunks.size(), static_cast<std::size_t>(threads) + 1);
    for (int t = 0; t < threads; ++t) workers.emplace_back([this] { work(); });
  }

  void work() {
    for (;;) {
      std::size_t i;
      {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [this] { return stop || next_job < window_end; });
        if (stop) return;
        i = next_job++;
      }
      Result r;
      try {
        std::vector<unsigned char> data;
        load_bytes(i, data);
        auto d = make_decoder(i, data);
        r.records.resize(static_cast<std::size_t>(chunks[i].points) * src.record_length);
        d->decode(r.records.data(), chunks[i].points);
        d->finish();
      } catch (const CorruptData& e) {
        r.records.clear();
        r.error = corrupt_message(i, e.what());
      } catch (const std::exception& e) {
        r.records.clear();
        r.error = e.what();
      }
      {
        std::lock_guard<std::mutex> lock(m);
        results[i] = std::move(r);
      }
      cv.notify_all();
    }
  }

  std::size_t read_parallel(unsigned char* dst, std::size_t n) {
    std::size_t done = 0;
    const std::size_t rl = src.record_length;
    while (done < n) {
      if (current_pos == current.records.size()) {
        if (next_chunk >= chunks.size()) break;
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [this] { return results.count(next_chunk) > 0; });
        current = std::move(results[next_chunk]);
        results.erase(next_chunk);
        cur = next_chunk++;
        current_pos = 0;
        window_end = std::min(chunks.size(), window_end + 1);
        lock.unlock();
        cv.notify_all();
        if (!current.error.empty()) {
          next_chunk = chunks.size();
          const std::string e = current.error;
          current = Result();
          throw IoError(e);
        }
      }
      const std::size_t k = std::min((current.records.size() - current_pos) / rl, n - done);
      std::memcpy(dst + done * rl, current.records.data() + current_pos, k * rl);
      current_pos += k * rl;
      done += k;
    }
    return done;
  }

  ~Impl() {
    {
      std::lock_guard<std::mutex> lock(m);
      stop = true;
    }
    cv.notify_all();
    for (auto& w : workers) w.join();
  }
};

LazStream::LazStream(const LazSource& source, int threads) : impl_(std::make_unique<Impl>(source)) {
  impl_->parse_vlr();
  impl_->read_chunk_table();
  std::uint64_t largest = 0;
  for (const Chunk& c : impl_->chunks) largest = std::max<std::uint64_t>(largest, c.points);
  if (threads > 1 && impl_->chunks.size() > 1 &&
      largest * source.record_length <= kMaxParallelChunkBytes) {
    // the workers start at the first read(): opening a file (read_header,
    // info) decodes nothing
    impl_->threads = std::min<int>(threads, static_cast<int>(impl_->chunks.size()));
  }
}

LazStream::~LazStream() = default;

std::size_t LazStream::read(unsigned char* dst, std::size_t n) {
  if (impl_->threads > 1 && impl_->workers.empty() && impl_->next_chunk == 0 && impl_->left == 0)
    impl_->start_workers();
  return impl_->workers.empty() ? impl_->read_sequential(dst, n) : impl_->read_parallel(dst, n);
}

std::string LazStream::description() const {
  const Impl& d = *impl_;
  std::string s = "LASzip " + d.version + ", ";
  s += d.compressor == 3 ? "layered" : "point-wise";
  s += " chunks of ";
  s += d.chunk_size == kVariableChunks ? std::string("variable size")
                                       : std::to_string(d.chunk_size) + " points";
  s += ", " + std::to_string(d.chunks.size()) + " chunks";
  return s;
}

}  // namespace citylod::io::detail
