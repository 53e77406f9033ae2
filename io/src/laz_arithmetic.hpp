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
// No read goes past the compressed bytes: compressed data that ends early
// sets the decoder's overrun() flag (the chunk decoders turn it into
// CorruptData after the batch of points), data that decodes to an impossible
// value throws CorruptData (the caller adds the file and chunk).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
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
  const unsigned char* data() const { return begin_; }
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
///
/// Every model has a decoder table (LASzip's has one for > 16 symbols only):
/// table[t] is the first symbol whose interval reaches t / table_size of the
/// range, so that a decode looks one symbol up and bisects only inside one
/// table cell. The table is sized at about 4 cells per symbol (16..2048
/// cells): with that, the common symbols own whole cells and most decodes do
/// not bisect at all (the bisection's mispredicted branches were a large part
/// of the decoder's cost; models of <= 16 symbols bisected over all symbols).
/// The table only speeds up the search: the symbol found is the one the
/// distribution defines, whatever the table size, so the decoded values are
/// LASzip's.
class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols);
  SymbolModel(SymbolModel&&) noexcept = default;
  SymbolModel& operator=(SymbolModel&&) noexcept = default;
  SymbolModel(const SymbolModel&) = delete;
  SymbolModel& operator=(const SymbolModel&) = delete;
  void update();

  std::uint32_t symbols;
  std::uint32_t last_symbol;
  std::uint32_t table_size = 0;
  std::uint32_t table_shift = 0;
  std::uint32_t total_count = 0;
  std::uint32_t update_cycle;
  std::uint32_t symbols_until_update;
  std::uint32_t* distribution = nullptr;      // symbols + 1 entries (the last one unused)
  std::uint32_t* symbol_count = nullptr;      // symbols entries
  std::uint16_t* decoder_table = nullptr;     // table_size + 2 entries
  std::unique_ptr<std::uint32_t[]> storage_;  // one allocation for the three arrays
};

#if defined(__GNUC__)
#define CITYLOD_LAZ_LIKELY(x) __builtin_expect(!!(x), 1)
#define CITYLOD_LAZ_UNLIKELY(x) __builtin_expect(!!(x), 0)
#define CITYLOD_LAZ_INLINE inline __attribute__((always_inline))
#else
#define CITYLOD_LAZ_LIKELY(x) (x)
#define CITYLOD_LAZ_UNLIKELY(x) (x)
#define CITYLOD_LAZ_INLINE inline
#endif

/// The range decoder. It reads its bytes straight from a contiguous buffer:
/// while 4 or more bytes are left, renormalisation loads a 32-bit word and
/// shifts in the 1-3 bytes it needs without a loop or a bounds check per byte;
/// near the end of the buffer it goes byte by byte and, past the end, shifts
/// in zeros and sets overrun() (never reads past the buffer). The chunk
/// decoders check overrun() after each batch of points and report the chunk
/// as corrupt: valid data never needs a byte beyond its chunk (layer).
class ArithmeticDecoder {
 public:
  static constexpr std::uint32_t kMinLength = 0x01000000u;
  static constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;
  static constexpr int kBitLengthShift = 13;
  static constexpr int kSymbolLengthShift = 15;

  /// Starts decoding at the current position of `src` and takes all of its
  /// remaining bytes (reads 4 of them now).
  void init(ByteSource& src) {
    if (src.remaining() < 4) throw CorruptData("compressed data ends early");
    p_ = src.data() + src.consumed();
    end_ = p_ + src.remaining();
    overrun_ = false;
    length_ = kMaxLength;
    value_ = 0;
    for (int i = 0; i < 4; ++i) value_ = (value_ << 8) | next_byte();
    if (value_ >= length_) throw CorruptData("invalid arithmetic-coder start");
  }

  /// True when the decoder has asked for bytes beyond its buffer (corrupt data).
  bool overrun() const { return overrun_; }
  /// Bytes of the buffer not consumed.
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

  CITYLOD_LAZ_INLINE std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t x = m.bit0_prob * (length_ >> kBitLengthShift);
    const std::uint32_t sym = value_ >= x;
    if (sym == 0) {
      length_ = x;
      ++m.bit0_count;
    } else {
      value_ -= x;
      length_ -= x;
    }
    renorm();
    if (--m.bits_until_update == 0) m.update();
    return sym;
  }

  CITYLOD_LAZ_INLINE std::uint32_t decode_symbol(SymbolModel& m) {
    const std::uint32_t full = length_;
    const std::uint32_t l = length_ >> kSymbolLengthShift;
    const std::uint32_t dv = div(value_, l);
    std::uint32_t t = dv >> m.table_shift;
    t = t < m.table_size ? t : m.table_size;  // > table_size only with corrupt data
    const std::uint32_t* dist = m.distribution;
    std::uint32_t sym = m.decoder_table[t];
    std::uint32_t n = m.decoder_table[t + 1] + 1u;
    while (n > sym + 1) {
      const std::uint32_t k = (sym + n) >> 1;
      if (dist[k] > dv)
        n = k;
      else
        sym = k;
    }
    const std::uint32_t x = dist[sym] * l;
    const std::uint32_t y = sym != m.last_symbol ? dist[sym + 1] * l : full;
    value_ -= x;
    length_ = y - x;
    if (CITYLOD_LAZ_UNLIKELY(length_ == 0)) bad_interval();
    renorm();
    ++m.symbol_count[sym];
    if (--m.symbols_until_update == 0) m.update();
    return sym;
  }

  /// `bits` (1..32) raw bits.
  CITYLOD_LAZ_INLINE std::uint32_t read_bits(std::uint32_t bits) {
    if (bits > 19) {
      const std::uint32_t low = read_short();
      const std::uint32_t high = read_bits_19(bits - 16);
      return (high << 16) | low;
    }
    return read_bits_19(bits);
  }
  std::uint32_t read_short() { return read_bits_19(16); }
  std::uint32_t read_int() {
    const std::uint32_t low = read_short();
    const std::uint32_t high = read_short();
    return (high << 16) | low;
  }
  std::uint64_t read_int64() {
    const std::uint64_t low = read_int();
    const std::uint64_t high = read_int();
    return (high << 32) | low;
  }

 private:
  // (a double-precision division is exact here too, but slower on our CPUs)
  static CITYLOD_LAZ_INLINE std::uint32_t div(std::uint32_t v, std::uint32_t l) { return v / l; }
  CITYLOD_LAZ_INLINE std::uint32_t read_bits_19(std::uint32_t bits) {
    const std::uint32_t sym = div(value_, length_ >>= bits);
    value_ -= length_ * sym;
    renorm();
    if (CITYLOD_LAZ_UNLIKELY(sym >= (1u << bits))) bad_raw_bits();
    return sym;
  }

  // Shifts in bytes until length_ >= kMinLength: (clz(length_) / 8) bytes,
  // 0..3 (1..3 when length_ < 2^24), taken from one big-endian 32-bit load.
  CITYLOD_LAZ_INLINE void renorm() {
    if (CITYLOD_LAZ_LIKELY(end_ - p_ >= 4)) {
      const std::uint32_t nb = static_cast<std::uint32_t>(__builtin_clz(length_ | 1u)) >> 3;
      const std::uint32_t s = nb << 3;
      const std::uint64_t w = (static_cast<std::uint64_t>(p_[0]) << 24) |
                              (static_cast<std::uint64_t>(p_[1]) << 16) |
                              (static_cast<std::uint64_t>(p_[2]) << 8) | p_[3];
      value_ =
          static_cast<std::uint32_t>((static_cast<std::uint64_t>(value_) << s) | (w >> (32 - s)));
      length_ = static_cast<std::uint32_t>(static_cast<std::uint64_t>(length_) << s);
      p_ += nb;
    } else if (length_ < kMinLength) {
      renorm_tail();
    }
  }
  void renorm_tail() {
    do {
      value_ = (value_ << 8) | next_byte();
    } while ((length_ <<= 8) < kMinLength);
  }
  std::uint32_t next_byte() {
    if (p_ == end_) {
      overrun_ = true;
      return 0;
    }
    return *p_++;
  }
  [[noreturn]] static void bad_interval();
  [[noreturn]] static void bad_raw_bits();

  const unsigned char* p_ = nullptr;
  const unsigned char* end_ = nullptr;
  std::uint32_t value_ = 0;
  std::uint32_t length_ = kMaxLength;
  bool overrun_ = false;
};

/// Decodes integers coded as a corrector to a prediction, in `contexts`
/// independent contexts, with `bits` significant bits (32: full int32 range).
class IntegerDecompressor {
 public:
  explicit IntegerDecompressor(std::uint32_t bits = 16, std::uint32_t contexts = 1,
                               std::uint32_t bits_high = 8, std::uint32_t range = 0);

  CITYLOD_LAZ_INLINE std::int32_t decompress(ArithmeticDecoder& dec, std::int32_t pred,
                                             std::uint32_t context = 0) {
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
  CITYLOD_LAZ_INLINE std::int32_t read_corrector(ArithmeticDecoder& dec, SymbolModel& m) {
    const std::uint32_t k = k_ = dec.decode_symbol(m);
    if (CITYLOD_LAZ_UNLIKELY(k == 0)) return static_cast<std::int32_t>(dec.decode_bit(corrector0_));
    if (CITYLOD_LAZ_UNLIKELY(k >= 32)) return corr_min_;
    std::int64_t c;
    if (k <= bits_high_) {
      c = dec.decode_symbol(correctors_[k]);
    } else {
      const std::uint32_t k1 = k - bits_high_;
      const std::uint32_t hi = dec.decode_symbol(correctors_[k]);
      const std::uint32_t lo = dec.read_bits(k1);
      c = (static_cast<std::int64_t>(hi) << k1) | lo;
    }
    // c in [0, 2^k): the upper half (bit k-1 set) codes 2^(k-1)+1 .. 2^k, the
    // lower half -(2^k-1) .. -2^(k-1). Without a branch: c + 1, minus 2^k in
    // the lower half.
    const std::int64_t lower = ((c >> (k - 1)) & 1) ^ 1;
    return static_cast<std::int32_t>(c + 1 - (lower << k));
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
