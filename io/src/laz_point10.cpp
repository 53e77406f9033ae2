// Point-wise LAZ chunks (LASzip compressor 2) of LAS point formats 0-5: the
// version-2 items POINT10, GPSTIME11, RGB12 and BYTE (extra bytes) and the
// version-1 WAVEPACKET13 (formats 4 and 5), all coded with one arithmetic
// decoder, item after item, point after point.
#include <array>
#include <cstring>

#include "laz_chunk.hpp"

namespace citylod::io::detail::laz {
namespace {

// Context tables of the POINT10 coder, indexed [number_of_returns][return_number]:
// which of 16 contexts (map) and which of 8 height predictors (level) a point uses.
constexpr std::uint8_t kReturnMap[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8},  {14, 0, 1, 3, 6, 10, 10, 9},
    {13, 1, 2, 4, 7, 11, 11, 10},    {12, 3, 4, 5, 8, 12, 12, 11},
    {11, 6, 7, 8, 9, 13, 13, 12},    {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15}};
constexpr std::uint8_t kReturnLevel[8][8] = {{0, 1, 2, 3, 4, 5, 6, 7}, {1, 0, 1, 2, 3, 4, 5, 6},
                                             {2, 1, 0, 1, 2, 3, 4, 5}, {3, 2, 1, 0, 1, 2, 3, 4},
                                             {4, 3, 2, 1, 0, 1, 2, 3}, {5, 4, 3, 2, 1, 0, 1, 2},
                                             {6, 5, 4, 3, 2, 1, 0, 1}, {7, 6, 5, 4, 3, 2, 1, 0}};

class ItemDecoder {
 public:
  virtual ~ItemDecoder() = default;
  virtual void decode(ArithmeticDecoder& dec, unsigned char* item) = 0;
};

// Lazily created 256-symbol models, one per previous byte value.
class ModelTable {
 public:
  SymbolModel& at(std::uint8_t i) {
    if (!models_[i]) models_[i] = std::make_unique<SymbolModel>(256);
    return *models_[i];
  }

 private:
  std::array<std::unique_ptr<SymbolModel>, 256> models_;
};

class Point10 final : public ItemDecoder {
 public:
  explicit Point10(const unsigned char* first) {
    x_ = load<std::int32_t>(first);
    y_ = load<std::int32_t>(first + 4);
    z_ = load<std::int32_t>(first + 8);
    intensity_ = 0;  // the coder starts from intensity 0, not the first point's
    bits_ = first[14];
    class_ = first[15];
    angle_ = first[16];
    user_ = first[17];
    source_ = load<std::uint16_t>(first + 18);
  }

  void decode(ArithmeticDecoder& dec, unsigned char* out) override {
    const std::uint32_t changed = dec.decode_symbol(changed_values_);
    std::uint32_t r, n, m, l;
    if (changed) {
      if (changed & 32) bits_ = static_cast<std::uint8_t>(dec.decode_symbol(bit_byte_.at(bits_)));
      r = bits_ & 7;
      n = (bits_ >> 3) & 7;
      m = kReturnMap[n][r];
      l = kReturnLevel[n][r];
      if (changed & 16) {
        intensity_ = static_cast<std::uint16_t>(
            ic_intensity_.decompress(dec, last_intensity_[m], m < 3 ? m : 3));
        last_intensity_[m] = intensity_;
      } else {
        intensity_ = last_intensity_[m];
      }
      if (changed & 8)
        class_ = static_cast<std::uint8_t>(dec.decode_symbol(classification_.at(class_)));
      if (changed & 4) {
        const int v = static_cast<int>(dec.decode_symbol(scan_angle_[(bits_ >> 6) & 1]));
        angle_ = fold_u8(v + angle_);
      }
      if (changed & 2) user_ = static_cast<std::uint8_t>(dec.decode_symbol(user_data_.at(user_)));
      if (changed & 1) source_ = static_cast<std::uint16_t>(ic_source_.decompress(dec, source_));
    } else {
      r = bits_ & 7;
      n = (bits_ >> 3) & 7;
      m = kReturnMap[n][r];
      l = kReturnLevel[n][r];
    }
    std::int32_t diff = ic_dx_.decompress(dec, median_x_[m].get(), n == 1);
    x_ = static_cast<std::int32_t>(static_cast<std::uint32_t>(x_) +
                                   static_cast<std::uint32_t>(diff));
    median_x_[m].add(diff);
    std::uint32_t kb = ic_dx_.k();
    diff = ic_dy_.decompress(dec, median_y_[m].get(), (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    y_ = static_cast<std::int32_t>(static_cast<std::uint32_t>(y_) +
                                   static_cast<std::uint32_t>(diff));
    median_y_[m].add(diff);
    kb = (ic_dx_.k() + ic_dy_.k()) / 2;
    z_ = ic_z_.decompress(dec, last_height_[l], (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
    last_height_[l] = z_;

    store(out, x_);
    store(out + 4, y_);
    store(out + 8, z_);
    store(out + 12, intensity_);
    out[14] = bits_;
    out[15] = class_;
    out[16] = angle_;
    out[17] = user_;
    store(out + 18, source_);
  }

 private:
  std::int32_t x_, y_, z_;
  std::uint16_t intensity_;
  std::uint8_t bits_, class_, angle_, user_;
  std::uint16_t source_;

  SymbolModel changed_values_{64};
  IntegerDecompressor ic_intensity_{16, 4};
  SymbolModel scan_angle_[2] = {SymbolModel(256), SymbolModel(256)};
  IntegerDecompressor ic_source_{16};
  ModelTable bit_byte_, classification_, user_data_;
  IntegerDecompressor ic_dx_{32, 2};
  IntegerDecompressor ic_dy_{32, 22};
  IntegerDecompressor ic_z_{32, 20};
  StreamingMedian5 median_x_[16], median_y_[16];
  std::uint16_t last_intensity_[16] = {};
  std::int32_t last_height_[8] = {};
};

// GPS time: up to 4 interleaved sequences, each predicted from its last
// integer difference (a multiple of it, or a fresh 32-bit difference, or a
// full 64-bit value when the jump is too large).
constexpr int kMulti = 500;
constexpr int kMultiMinus = -10;
constexpr int kMultiUnchanged = kMulti - kMultiMinus + 1;  // 511
constexpr int kMultiCodeFull = kMulti - kMultiMinus + 2;   // 512
constexpr int kMultiTotal = kMulti - kMultiMinus + 6;      // 516

inline std::int32_t mul_wrap(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
}

class GpsTime11 final : public ItemDecoder {
 public:
  explicit GpsTime11(const unsigned char* first) { time_[0] = load<std::uint64_t>(first); }

  void decode(ArithmeticDecoder& dec, unsigned char* out) override {
    for (int guard = 0;; ++guard) {
      if (guard > 8) throw CorruptData("GPS time: endless sequence switches");
      if (diff_[last_] == 0) {
        const int multi = static_cast<int>(dec.decode_symbol(zero_diff_));
        if (multi == 1) {
          diff_[last_] = ic_.decompress(dec, 0, 0);
          time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(diff_[last_]));
          extreme_[last_] = 0;
        } else if (multi == 2) {
          full_time(dec);
        } else if (multi > 2) {
          last_ = (last_ + multi - 2) & 3;
          continue;
        }
      } else {
        int multi = static_cast<int>(dec.decode_symbol(multi_));
        if (multi == 1) {
          time_[last_] += static_cast<std::uint64_t>(
              static_cast<std::int64_t>(ic_.decompress(dec, diff_[last_], 1)));
          extreme_[last_] = 0;
        } else if (multi < kMultiUnchanged) {
          std::int32_t d;
          if (multi == 0) {
            d = ic_.decompress(dec, 0, 7);
            extreme(d);
          } else if (multi < kMulti) {
            d = ic_.decompress(dec, mul_wrap(multi, diff_[last_]), multi < 10 ? 2 : 3);
          } else if (multi == kMulti) {
            d = ic_.decompress(dec, mul_wrap(kMulti, diff_[last_]), 4);
            extreme(d);
          } else {
            multi = kMulti - multi;
            if (multi > kMultiMinus) {
              d = ic_.decompress(dec, mul_wrap(multi, diff_[last_]), 5);
            } else {
              d = ic_.decompress(dec, mul_wrap(kMultiMinus, diff_[last_]), 6);
              extreme(d);
            }
          }
          time_[last_] += static_cast<std::uint64_t>(static_cast<std::int64_t>(d));
        } else if (multi == kMultiCodeFull) {
          full_time(dec);
        } else if (multi > kMultiCodeFull) {
          last_ = (last_ + multi - kMultiCodeFull) & 3;
          continue;
        }
      }
      break;
    }
    store(out, time_[last_]);
  }

 private:
  void extreme(std::int32_t d) {
    if (++extreme_[last_] > 3) {
      diff_[last_] = d;
      extreme_[last_] = 0;
    }
  }
  void full_time(ArithmeticDecoder& dec) {
    next_ = (next_ + 1) & 3;
    const std::uint32_t high = static_cast<std::uint32_t>(
        ic_.decompress(dec, static_cast<std::int32_t>(time_[last_] >> 32), 8));
    time_[next_] = (static_cast<std::uint64_t>(high) << 32) | dec.read_int();
    last_ = next_;
    diff_[last_] = 0;
    extreme_[last_] = 0;
  }

  SymbolModel multi_{kMultiTotal};
  SymbolModel zero_diff_{6};
  IntegerDecompressor ic_{32, 9};
  std::uint64_t time_[4] = {0, 0, 0, 0};
  std::int32_t diff_[4] = {0, 0, 0, 0};
  int extreme_[4] = {0, 0, 0, 0};
  int last_ = 0, next_ = 0;
};

}  // namespace

void decode_rgb(ArithmeticDecoder& dec, RgbModels& m, const std::uint16_t last[3],
                std::uint16_t out[3]) {
  const std::uint32_t sym = dec.decode_symbol(m.byte_used);
  int corr;
  if (sym & 1) {
    corr = static_cast<int>(dec.decode_symbol(m.diff[0]));
    out[0] = fold_u8(corr + (last[0] & 255));
  } else {
    out[0] = last[0] & 0xFF;
  }
  if (sym & 2) {
    corr = static_cast<int>(dec.decode_symbol(m.diff[1]));
    out[0] |= static_cast<std::uint16_t>(fold_u8(corr + (last[0] >> 8)) << 8);
  } else {
    out[0] |= last[0] & 0xFF00;
  }
  if (sym & 64) {
    int diff = (out[0] & 0xFF) - (last[0] & 0xFF);
    if (sym & 4) {
      corr = static_cast<int>(dec.decode_symbol(m.diff[2]));
      out[1] = fold_u8(corr + clamp_u8(diff + (last[1] & 255)));
    } else {
      out[1] = last[1] & 0xFF;
    }
    if (sym & 16) {
      corr = static_cast<int>(dec.decode_symbol(m.diff[4]));
      diff = (diff + ((out[1] & 0xFF) - (last[1] & 0xFF))) / 2;
      out[2] = fold_u8(corr + clamp_u8(diff + (last[2] & 255)));
    } else {
      out[2] = last[2] & 0xFF;
    }
    diff = (out[0] >> 8) - (last[0] >> 8);
    if (sym & 8) {
      corr = static_cast<int>(dec.decode_symbol(m.diff[3]));
      out[1] |= static_cast<std::uint16_t>(fold_u8(corr + clamp_u8(diff + (last[1] >> 8))) << 8);
    } else {
      out[1] |= last[1] & 0xFF00;
    }
    if (sym & 32) {
      corr = static_cast<int>(dec.decode_symbol(m.diff[5]));
      diff = (diff + ((out[1] >> 8) - (last[1] >> 8))) / 2;
      out[2] |= static_cast<std::uint16_t>(fold_u8(corr + clamp_u8(diff + (last[2] >> 8))) << 8);
    } else {
      out[2] |= last[2] & 0xFF00;
    }
  } else {
    out[1] = out[0];
    out[2] = out[0];
  }
}

void decode_wavepacket(ArithmeticDecoder& dec, WavepacketModels& m, const unsigned char* last,
                       unsigned char* out) {
  out[0] = static_cast<unsigned char>(dec.decode_symbol(m.packet_index));
  const std::uint64_t last_offset = load<std::uint64_t>(last + 1);
  const std::uint32_t last_size = load<std::uint32_t>(last + 9);
  m.last_offset_sym = dec.decode_symbol(m.offset_diff[m.last_offset_sym]);
  std::uint64_t offset;
  switch (m.last_offset_sym) {
    case 0:  // the same packet as the last point (another return of the pulse)
      offset = last_offset;
      break;
    case 1:  // the packet right after the last one
      offset = last_offset + last_size;
      break;
    case 2:
      m.last_offset_diff = m.ic_offset_diff.decompress(dec, m.last_offset_diff);
      offset =
          last_offset + static_cast<std::uint64_t>(static_cast<std::int64_t>(m.last_offset_diff));
      break;
    default:
      offset = dec.read_int64();
      break;
  }
  store(out + 1, offset);
  store(out + 9, m.ic_packet_size.decompress(dec, load<std::int32_t>(last + 9)));
  // the floats (return point, dx, dy, dz) are predicted as the integers of their bits
  store(out + 13, m.ic_return_point.decompress(dec, load<std::int32_t>(last + 13)));
  for (std::uint32_t a = 0; a < 3; ++a)
    store(out + 17 + 4 * a, m.ic_xyz.decompress(dec, load<std::int32_t>(last + 17 + 4 * a), a));
}

namespace {

class Wavepacket13 final : public ItemDecoder {
 public:
  explicit Wavepacket13(const unsigned char* first) { std::memcpy(last_, first, sizeof last_); }
  void decode(ArithmeticDecoder& dec, unsigned char* out) override {
    decode_wavepacket(dec, models_, last_, out);
    std::memcpy(last_, out, sizeof last_);
  }

 private:
  WavepacketModels models_;
  unsigned char last_[29];
};

class Rgb12 final : public ItemDecoder {
 public:
  explicit Rgb12(const unsigned char* first) {
    for (int i = 0; i < 3; ++i) last_[i] = load<std::uint16_t>(first + 2 * i);
  }
  void decode(ArithmeticDecoder& dec, unsigned char* out) override {
    std::uint16_t c[3];
    decode_rgb(dec, models_, last_, c);
    for (int i = 0; i < 3; ++i) {
      store(out + 2 * i, c[i]);
      last_[i] = c[i];
    }
  }

 private:
  RgbModels models_;
  std::uint16_t last_[3];
};

class Bytes final : public ItemDecoder {
 public:
  Bytes(const unsigned char* first, std::size_t n) : last_(first, first + n) {
    models_.reserve(n);
    for (std::size_t i = 0; i < n; ++i) models_.emplace_back(256);
  }
  void decode(ArithmeticDecoder& dec, unsigned char* out) override {
    for (std::size_t i = 0; i < last_.size(); ++i) {
      last_[i] = fold_u8(last_[i] + static_cast<int>(dec.decode_symbol(models_[i])));
      out[i] = last_[i];
    }
  }

 private:
  std::vector<unsigned char> last_;
  std::vector<SymbolModel> models_;
};

class PointwiseChunk final : public ChunkDecoder {
 public:
  PointwiseChunk(const std::vector<Item>& items, ByteSource data) : src_(data), items_(items) {
    for (const Item& it : items_) record_length_ += it.size;
  }

  void decode(unsigned char* dst, std::size_t n) override {
    for (std::size_t i = 0; i < n; ++i, dst += record_length_) {
      if (decoders_.empty()) {
        start(dst);
        continue;
      }
      if (p10_) {  // the usual item order: direct calls, no virtual dispatch per item
        p10_->decode(dec_, dst);
        if (gps_) gps_->decode(dec_, dst + gps_off_);
        if (rgb_) rgb_->decode(dec_, dst + rgb_off_);
        if (wave_) wave_->decode(dec_, dst + wave_off_);
        if (bytes_) bytes_->decode(dec_, dst + bytes_off_);
        continue;
      }
      std::size_t off = 0;
      for (std::size_t k = 0; k < decoders_.size(); ++k) {
        decoders_[k]->decode(dec_, dst + off);
        off += items_[k].size;
      }
    }
    if (dec_.overrun()) throw CorruptData("compressed data ends early");
  }

  void finish() override {
    const std::size_t left = decoders_.empty() ? src_.remaining() : dec_.remaining();
    if (left != 0)
      throw CorruptData("the decoded points end " + std::to_string(left) +
                        " bytes before the chunk does");
  }

 private:
  // The first point of a chunk is stored raw; the coder starts after it.
  void start(unsigned char* dst) {
    src_.get_bytes(dst, record_length_);
    std::size_t off = 0;
    for (const Item& it : items_) {
      const unsigned char* p = dst + off;
      switch (it.type) {
        case kPoint10:
          decoders_.push_back(std::make_unique<Point10>(p));
          break;
        case kGpsTime11:
          decoders_.push_back(std::make_unique<GpsTime11>(p));
          break;
        case kRgb12:
          decoders_.push_back(std::make_unique<Rgb12>(p));
          break;
        case kWavepacket13:
          decoders_.push_back(std::make_unique<Wavepacket13>(p));
          break;
        default:
          decoders_.push_back(std::make_unique<Bytes>(p, it.size));
          break;
      }
      off += it.size;
    }
    // POINT10 [GPSTIME11] [RGB12] [WAVEPACKET13] [BYTE]: the item order of
    // formats 0-5 (and every LASzip writer); anything else takes the generic loop
    std::size_t k = 0;
    off = 0;
    Point10* p10 = nullptr;
    if (k < items_.size() && items_[k].type == kPoint10) {
      p10 = static_cast<Point10*>(decoders_[k].get());
      off += items_[k++].size;
    }
    if (k < items_.size() && items_[k].type == kGpsTime11) {
      gps_ = static_cast<GpsTime11*>(decoders_[k].get());
      gps_off_ = off;
      off += items_[k++].size;
    }
    if (k < items_.size() && items_[k].type == kRgb12) {
      rgb_ = static_cast<Rgb12*>(decoders_[k].get());
      rgb_off_ = off;
      off += items_[k++].size;
    }
    if (k < items_.size() && items_[k].type == kWavepacket13) {
      wave_ = static_cast<Wavepacket13*>(decoders_[k].get());
      wave_off_ = off;
      off += items_[k++].size;
    }
    if (k < items_.size() && items_[k].type == kByte) {
      bytes_ = static_cast<Bytes*>(decoders_[k].get());
      bytes_off_ = off;
      off += items_[k++].size;
    }
    if (k == items_.size()) p10_ = p10;
    dec_.init(src_);
  }

  ByteSource src_;
  std::vector<Item> items_;
  std::size_t record_length_ = 0;
  ArithmeticDecoder dec_;
  std::vector<std::unique_ptr<ItemDecoder>> decoders_;
  Point10* p10_ = nullptr;  // set when the items are in the usual order
  GpsTime11* gps_ = nullptr;
  Rgb12* rgb_ = nullptr;
  Wavepacket13* wave_ = nullptr;
  Bytes* bytes_ = nullptr;
  std::size_t gps_off_ = 0, rgb_off_ = 0, wave_off_ = 0, bytes_off_ = 0;
};

}  // namespace

std::unique_ptr<ChunkDecoder> make_pointwise_decoder(const std::vector<Item>& items,
                                                     ByteSource data) {
  return std::make_unique<PointwiseChunk>(items, data);
}

}  // namespace citylod::io::detail::laz
