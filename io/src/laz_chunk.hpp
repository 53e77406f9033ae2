// Private: decoders of one LAZ chunk (a run of points coded independently of
// the rest of the file: the first point raw, the others predicted from it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "laz_arithmetic.hpp"

namespace citylod::io::detail::laz {

/// LASzip item types (the "items" of the laszip VLR).
enum ItemType : std::uint16_t {
  kByte = 0,
  kPoint10 = 6,
  kGpsTime11 = 7,
  kRgb12 = 8,
  kWavepacket13 = 9,
  kPoint14 = 10,
  kRgb14 = 11,
  kRgbNir14 = 12,
  kWavepacket14 = 13,
  kByte14 = 14,
};

/// A little-endian value at `p` (unaligned), and its write: the record
/// layout the decoders read their predictions from and write into.
template <typename T>
T load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <typename T>
void store(unsigned char* p, T v) {
  std::memcpy(p, &v, sizeof v);
}

struct Item {
  std::uint16_t type = 0;
  std::uint16_t size = 0;
  std::uint16_t version = 0;
};

/// Human name of an item ("POINT10 v2"), for messages.
std::string item_name(const Item& item);

/// One chunk being decoded. The records are written in LAS record layout
/// (items concatenated in VLR order), record_length bytes each.
class ChunkDecoder {
 public:
  virtual ~ChunkDecoder() = default;
  /// Decodes the next n records into dst. Throws CorruptData.
  virtual void decode(unsigned char* dst, std::size_t n) = 0;
  /// After the chunk's last point: throws CorruptData when the compressed
  /// bytes were not consumed as the coder wrote them.
  virtual void finish() {}
};

/// The 7 models of a colour (RGB12 v2 and RGB14 v3 code colours alike).
struct RgbModels {
  SymbolModel byte_used{128};
  SymbolModel diff[6] = {SymbolModel(256), SymbolModel(256), SymbolModel(256),
                         SymbolModel(256), SymbolModel(256), SymbolModel(256)};
};
/// Decodes one colour (3 x 16 bit) against the previous one.
void decode_rgb(ArithmeticDecoder& dec, RgbModels& m, const std::uint16_t last[3],
                std::uint16_t out[3]);

/// The models of a waveform packet (WAVEPACKET13 v1 and WAVEPACKET14 v3/v4
/// code the 29-byte packet alike): the descriptor index, how the data offset
/// moved (same, + last packet size, + a 32-bit difference, or a raw 64-bit
/// value), then size, return point and dx/dy/dz as integer differences.
struct WavepacketModels {
  SymbolModel packet_index{256};
  SymbolModel offset_diff[4] = {SymbolModel(4), SymbolModel(4), SymbolModel(4), SymbolModel(4)};
  IntegerDecompressor ic_offset_diff{32}, ic_packet_size{32}, ic_return_point{32};
  IntegerDecompressor ic_xyz{32, 3};
  std::int32_t last_offset_diff = 0;
  std::uint32_t last_offset_sym = 0;
};
/// Decodes one packet (29 bytes: descriptor index, u64 offset, u32 size,
/// f32 return point, f32 dx, dy, dz) predicted from `last` (the same layout).
void decode_wavepacket(ArithmeticDecoder& dec, WavepacketModels& m, const unsigned char* last,
                       unsigned char* out);

/// Point-wise chunk (compressor 2): POINT10, GPSTIME11, RGB12, BYTE items v2
/// and WAVEPACKET13 v1.
/// `data` must stay alive while the decoder is used.
std::unique_ptr<ChunkDecoder> make_pointwise_decoder(const std::vector<Item>& items,
                                                     ByteSource data);

/// Layered chunk (compressor 3): POINT14, RGB14, RGBNIR14, WAVEPACKET14, BYTE14
/// items v3/v4.
/// `points` is the chunk's point count from the chunk table (checked against
/// the count stored in the chunk).
std::unique_ptr<ChunkDecoder> make_layered_decoder(const std::vector<Item>& items, ByteSource data,
                                                   std::uint64_t points);

}  // namespace citylod::io::detail::laz
