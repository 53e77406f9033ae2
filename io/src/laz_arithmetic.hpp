// Private: the entropy decoder of LASzip-compressed point data (LAZ).
//
// LASzip uses an adaptive binary-range ("arithmetic") coder after Amir Said's
// FastAC: 32-bit base/length, renormalisation one byte at a time, adaptive
// symbol models of 2..2048 symbols (distribution recomputed every
// update_cycle symbols) and adaptive bit models. On top of it, integers are
// coded as a corrector to a prediction: first the number k of significant bits
// of the corrector (a symbol model per context), then the corrector itself in
// [-(2^k - 1), 2^k] (a model per k for its high bits, raw bits for the rest).
// This file is written from the format's public description and the LASzip
// sources as reference; it decodes only.
//
// Every read is bounds-checked: compressed data that ends early or decodes to
// an impossible value throws CorruptData (the caller adds the file and chunk).
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace citylod::io::detail::laz {

/// Thrown by the decoders on malformed compressed data; the reader turns it
/// into an IoError naming the file and the chunk.
class CorruptData : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A bounded view of compressed bytes.
class ByteSource {
 public:
  ByteSource() = default;
  ByteSource(const unsigned char* data, std::size_t size)
      : begin_(data), p_(data), end_(data + size) {}

  unsigned char get() {
    if (p_ == end_) throw CorruptData("compressed data ends early");
    return *p_++;
  }
  std::uint32_t get_u32le() {
    std::uint32_t v = get();
    v |= static_cast<std::uint32_t>(get()) << 8;
    v |= static_cast<std::uint32_t>(get()) << 16;
    v |= static_cast<std::uint32_t>(get()) << 24;
    return v;
  }
  /// Copies n raw bytes.
  void get_bytes(unsigned char* dst, std::size_t n);
  /// A sub-view of the next n bytes (consumed here).
  ByteSource take(std::size_t n);

  std::size_t consumed() const { return static_cast<std::size_t>(p_ - begin_); }
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

 private:
  const unsigned char* begin_ = nullptr;
  const unsigned char* p_ = nullptr;
  const unsigned char* end_ = nullptr;
};

/// Adaptive model of one binary decision.
class BitModel {
 public:
  BitModel() = default;
  void update();

  std::uint32_t bit0_count = 1;
  std::uint32_t bit_count = 2;
  std::uint32_t bit0_prob = 1u << 12;  // 2^(length shift - 1)
  std::uint32_t update_cycle = 4;
  std::uint32_t bits_until_update = 4;
};

/// Adaptive model of `symbols` symbols (2..2048), initially uniform.
class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols);
  void update();

  std::uint32_t symbols;
  std::uint32_t last_symbol;
  std::uint32_t table_size = 0;  // 0: no decoder table (<= 16 symbols)
  std::uint32_t table_shift = 0;
  std::uint32_t total_count = 0;
  std::uint32_t update_cycle;
  std::uint32_t symbols_until_update;
  std::vector<std::uint32_t> distribution;   // symbols entries
  std::vector<std::uint32_t> symbol_count;   // symbols entries
  std::vector<std::uint32_t> decoder_table;  // table_size + 2 entries
};

class ArithmeticDecoder {
 public:
  static constexpr std::uint32_t kMinLength = 0x01000000u;
  static constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;
  static constexpr int kBitLengthShift = 13;
  static constexpr int kSymbolLengthShift = 15;

  /// Starts decoding at the current position of `src` (reads 4 bytes).
  void init(ByteSource* src) {
    src_ = src;
    length_ = kMaxLength;
    value_ = static_cast<std::uint32_t>(src->get()) << 24;
    value_ |= static_cast<std::uint32_t>(src->get()) << 16;
    value_ |= static_cast<std::uint32_t>(src->get()) << 8;
    value_ |= static_cast<std::uint32_t>(src->get());
    if (value_ >= length_) throw CorruptData("invalid arithmetic-coder start");
  }

  std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t x = m.bit0_prob * (length_ >> kBitLengthShift);
    const std::uint32_t sym = value_ >= x;
    if (sym == 0) {
      length_ = x;
      ++m.bit0_count;
    } else {
      value_ -= x;
      length_ -= x;
    }
    if (length_ < kMinLength) renorm();
    if (--m.bits_until_update == 0) m.update();
    return sym;
  }

  std::uint32_t decode_symbol(SymbolModel& m) {
    std::uint32_t n, sym, x, y = length_;
    if (m.table_size) {
      const std::uint32_t dv = value_ / (length_ >>= kSymbolLengthShift);
      std::uint32_t t = dv >> m.table_shift;
      if (t > m.table_size) t = m.table_size;  // only reachable with corrupt data
      sym = m.decoder_table[t];
      n = m.decoder_table[t + 1] + 1;
      while (n > sym + 1) {
        const std::uint32_t k = (sym + n) >> 1;
        if (m.distribution[k] > dv)
          n = k;
        else
          sym = k;
      }
      x = m.distribution[sym] * length_;
      if (sym != m.last_symbol) y = m.distribution[sym + 1] * length_;
    } else {
      x = sym = 0;
      length_ >>= kSymbolLengthShift;
      n = m.symbols;
      std::uint32_t k = n >> 1;
      do {
        const std::uint32_t z = length_ * m.distribution[k];
        if (z > value_) {
          n = k;
          y = z;
        } else {
          sym = k;
          x = z;
        }
      } while ((k = (sym + n) >> 1) != sym);
    }
    value_ -= x;
    length_ = y - x;
    if (length_ == 0) throw CorruptData("invalid arithmetic-coder interval");
    if (length_ < kMinLength) renorm();
    ++m.symbol_count[sym];
    if (--m.symbols_until_update == 0) m.update();
    return sym;
  }

  /// `bits` (1..32) raw bits.
  std::uint32_t read_bits(std::uint32_t bits) {
    if (bits > 19) {
      const std::uint32_t low = read_short();
      const std::uint32_t high = read_bits(bits - 16);
      return (high << 16) | low;
    }
    const std::uint32_t sym = value_ / (length_ >>= bits);
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    if (sym >= (1u << bits)) throw CorruptData("raw bits out of range");
    return sym;
  }
  std::uint32_t read_short() {
    const std::uint32_t sym = value_ / (length_ >>= 16);
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    if (sym >= (1u << 16)) throw CorruptData("raw bits out of range");
    return sym;
  }
  std::uint32_t read_int() {
    const std::uint32_t low = read_short();
    const std::uint32_t high = read_short();
    return (high << 16) | low;
  }

 private:
  void renorm() {
    do {
      value_ = (value_ << 8) | src_->get();
    } while ((length_ <<= 8) < kMinLength);
  }

  ByteSource* src_ = nullptr;
  std::uint32_t value_ = 0;
  std::uint32_t length_ = kMaxLength;
};

/// Decodes integers coded as a corrector to a prediction, in `contexts`
/// independent contexts, with `bits` significant bits (32: full int32 range).
class IntegerDecompressor {
 public:
  explicit IntegerDecompressor(std::uint32_t bits = 16, std::uint32_t contexts = 1,
                               std::uint32_t bits_high = 8, std::uint32_t range = 0);

  std::int32_t decompress(ArithmeticDecoder& dec, std::int32_t pred, std::uint32_t context = 0) {
    const std::int32_t corr = read_corrector(dec, bits_models_[context]);
    // wrap-around arithmetic as in the coder (two's complement, then fold into range)
    std::int64_t real = static_cast<std::int64_t>(pred) + corr;
    if (corr_range_ != 0) {
      if (real < 0)
        real += corr_range_;
      else if (real >= static_cast<std::int64_t>(corr_range_))
        real -= corr_range_;
    }
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(real));
  }
  /// Number of corrector bits k of the last decompress().
  std::uint32_t k() const { return k_; }

 private:
  std::int32_t read_corrector(ArithmeticDecoder& dec, SymbolModel& m) {
    k_ = dec.decode_symbol(m);
    if (k_ == 0) return static_cast<std::int32_t>(dec.decode_bit(corrector0_));
    if (k_ >= 32) return corr_min_;
    std::int64_t c;
    if (k_ <= bits_high_) {
      c = dec.decode_symbol(correctors_[k_]);
    } else {
      const std::uint32_t k1 = k_ - bits_high_;
      const std::uint32_t hi = dec.decode_symbol(correctors_[k_]);
      const std::uint32_t lo = dec.read_bits(k1);
      c = (static_cast<std::int64_t>(hi) << k1) | lo;
    }
    if (c >= (std::int64_t{1} << (k_ - 1)))
      c += 1;
    else
      c -= (std::int64_t{1} << k_) - 1;
    return static_cast<std::int32_t>(c);
  }

  std::uint32_t bits_high_;
  std::uint32_t corr_bits_;
  std::uint32_t corr_range_;
  std::int32_t corr_min_;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> bits_models_;  // one per context, corr_bits + 1 symbols
  BitModel corrector0_;
  std::vector<SymbolModel> correctors_;  // index 1..corr_bits (0 unused)
};

/// The "streaming median of 5" predictor of coordinate differences.
struct StreamingMedian5 {
  std::int32_t values[5] = {0, 0, 0, 0, 0};
  bool high = true;

  std::int32_t get() const { return values[2]; }
  void add(std::int32_t v);
};

inline std::uint8_t fold_u8(int v) {
  return static_cast<std::uint8_t>(v < 0 ? v + 256 : (v > 255 ? v - 256 : v));
}
inline int clamp_u8(int v) {
  return v <= 0 ? 0 : (v >= 255 ? 255 : v);
}

}  // namespace citylod::io::detail::laz
