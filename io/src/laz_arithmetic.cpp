// The adaptive models and the integer decompressor of the LAZ entropy decoder.
#include "laz_arithmetic.hpp"

#include <cstring>

namespace citylod::io::detail::laz {

void ByteSource::get_bytes(unsigned char* dst, std::size_t n) {
  if (n > remaining()) throw CorruptData("compressed data ends early");
  std::memcpy(dst, p_, n);
  p_ += n;
}

ByteSource ByteSource::take(std::size_t n) {
  if (n > remaining()) throw CorruptData("compressed data ends early");
  ByteSource s(p_, n);
  p_ += n;
  return s;
}

void BitModel::update() {
  constexpr std::uint32_t kMaxCount = 1u << 13;
  if ((bit_count += update_cycle) > kMaxCount) {
    bit_count = (bit_count + 1) >> 1;
    bit0_count = (bit0_count + 1) >> 1;
    if (bit0_count == bit_count) ++bit_count;
  }
  const std::uint32_t scale = 0x80000000u / bit_count;
  bit0_prob = (bit0_count * scale) >> (31 - ArithmeticDecoder::kBitLengthShift);
  update_cycle = (5 * update_cycle) >> 2;
  if (update_cycle > 64) update_cycle = 64;
  bits_until_update = update_cycle;
}

void ArithmeticDecoder::bad_interval() {
  throw CorruptData("invalid arithmetic-coder interval");
}
void ArithmeticDecoder::bad_raw_bits() {
  throw CorruptData("raw bits out of range");
}

SymbolModel::SymbolModel(std::uint32_t n) : symbols(n), last_symbol(n - 1) {
  if (n < 2 || n > (1u << 11)) throw CorruptData("bad symbol model size");
  // about 4 table cells per symbol, 16 .. 2048 cells (8 per symbol removed a
  // few more bisections but cost more in update() than it saved)
  std::uint32_t table_bits = 4;
  while (table_bits < 11 && (1u << table_bits) < 4 * n) ++table_bits;
  table_size = 1u << table_bits;
  table_shift = ArithmeticDecoder::kSymbolLengthShift - table_bits;
  const std::size_t words = (n + 1) + n + (table_size + 2 + 1) / 2;
  storage_.reset(new std::uint32_t[words]);  // all set by update()
  distribution = storage_.get();
  symbol_count = distribution + n + 1;
  decoder_table = reinterpret_cast<std::uint16_t*>(symbol_count + n);
  for (std::uint32_t k = 0; k < n; ++k) symbol_count[k] = 1;
  update_cycle = n;
  update();
  symbols_until_update = update_cycle = (n + 6) >> 1;
}

void SymbolModel::update() {
  constexpr std::uint32_t kMaxCount = 1u << 15;
  if ((total_count += update_cycle) > kMaxCount) {
    total_count = 0;
    for (std::uint32_t k = 0; k < symbols; ++k)
      total_count += (symbol_count[k] = (symbol_count[k] + 1) >> 1);
  }
  std::uint32_t sum = 0, s = 0;
  const std::uint32_t scale = 0x80000000u / total_count;
  constexpr int kShift = 31 - ArithmeticDecoder::kSymbolLengthShift;
  // table[j] (j >= 1) = (number of symbols k with distribution[k] >> table_shift < j) - 1,
  // i.e. the symbol whose interval holds the start of cell j; built as a
  // histogram and its prefix sums (no data-dependent branches).
  std::uint16_t* table = decoder_table;
  std::memset(table, 0, (table_size + 2) * sizeof *table);
  for (std::uint32_t k = 0; k < symbols; ++k) {
    distribution[k] = (scale * sum) >> kShift;
    sum += symbol_count[k];
    ++table[(distribution[k] >> table_shift) + 1];
  }
  for (std::uint32_t j = 1; j <= table_size + 1; ++j) {
    s += table[j];
    table[j] = static_cast<std::uint16_t>(s - 1);
  }
  table[0] = 0;
  update_cycle = (5 * update_cycle) >> 2;
  const std::uint32_t max_cycle = (symbols + 6) << 3;
  if (update_cycle > max_cycle) update_cycle = max_cycle;
  symbols_until_update = update_cycle;
}

IntegerDecompressor::IntegerDecompressor(std::uint32_t bits, std::uint32_t contexts,
                                         std::uint32_t bits_high, std::uint32_t range)
    : bits_high_(bits_high) {
  if (range) {
    corr_bits_ = 0;
    corr_range_ = range;
    while (range) {
      range >>= 1;
      ++corr_bits_;
    }
    if (corr_range_ == (1u << (corr_bits_ - 1))) --corr_bits_;
    corr_min_ = -static_cast<std::int32_t>(corr_range_ / 2);
  } else if (bits && bits < 32) {
    corr_bits_ = bits;
    corr_range_ = 1u << bits;
    corr_min_ = -static_cast<std::int32_t>(corr_range_ / 2);
  } else {
    corr_bits_ = 32;
    corr_range_ = 0;
    corr_min_ = INT32_MIN;
  }
  bits_models_.reserve(contexts);
  for (std::uint32_t i = 0; i < contexts; ++i) bits_models_.emplace_back(corr_bits_ + 1);
  correctors_.reserve(corr_bits_ + 1);
  correctors_.emplace_back(2);  // placeholder for k = 0 (a bit model is used)
  for (std::uint32_t i = 1; i <= corr_bits_; ++i)
    correctors_.emplace_back(i <= bits_high_ ? (1u << i) : (1u << bits_high_));
}

void StreamingMedian5::add(std::int32_t v) {
  std::int32_t* x = values;
  if (high) {
    if (v < x[2]) {
      x[4] = x[3];
      x[3] = x[2];
      if (v < x[0]) {
        x[2] = x[1];
        x[1] = x[0];
        x[0] = v;
      } else if (v < x[1]) {
        x[2] = x[1];
        x[1] = v;
      } else {
        x[2] = v;
      }
    } else {
      if (v < x[3]) {
        x[4] = x[3];
        x[3] = v;
      } else {
        x[4] = v;
      }
      high = false;
    }
  } else {
    if (x[2] < v) {
      x[0] = x[1];
      x[1] = x[2];
      if (x[4] < v) {
        x[2] = x[3];
        x[3] = x[4];
        x[4] = v;
      } else if (x[3] < v) {
        x[2] = x[3];
        x[3] = v;
      } else {
        x[2] = v;
      }
    } else {
      if (x[1] < v) {
        x[0] = x[1];
        x[1] = v;
      } else {
        x[0] = v;
      }
      high = true;
    }
  }
}

}  // namespace citylod::io::detail::laz
