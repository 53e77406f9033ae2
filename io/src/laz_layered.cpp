// Layered LAZ chunks (LASzip compressor 3, "native LAS 1.4" compression) of
// point formats 6-10: items POINT14, RGB14, RGBNIR14, WAVEPACKET14 and BYTE14,
// versions 3 and 4.
//
// Versions 3 and 4 differ only in the scanner-channel contexts of the items
// after POINT14 (LASzip 3's reader and writer agree on both, so v3 files
// need v3's rules): POINT14 v3 hands its channel to the other items only at
// the point where the channel changes, at every other point they get channel
// 0; and a v3 item that switches back to a channel it has seen before
// predicts that one point from (and stores it in) the channel it leaves.
// Version 4 hands the channel on always and predicts from the new channel.
//
// A chunk holds its first point raw, the number of points, the byte size of
// every layer, then the layers. Each layer (XY + returns, Z, classification,
// flags, intensity, scan angle, user data, point source, GPS time, RGB, NIR,
// each extra byte) has its own arithmetic decoder; a layer of size 0 means the
// field does not change within the chunk. Every scanner channel (0-3) has its
// own prediction context, created from the previous channel's last point.
#include <array>
#include <cstring>

#include "laz_chunk.hpp"

namespace citylod::io::detail::laz {
namespace {

constexpr std::uint8_t kReturnMap6[16][16] = {{0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5},
                                              {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
                                              {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3},
                                              {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                              {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                              {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                              {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4},
                                              {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
                                              {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4},
                                              {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
                                              {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4},
                                              {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
                                              {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4},
                                              {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
                                              {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5},
                                              {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5}};

// |n - r| clamped to 7: which of 8 height predictors a point uses.
inline std::uint32_t return_level8(std::uint32_t n, std::uint32_t r) {
  const std::uint32_t d = n > r ? n - r : r - n;
  return d < 7 ? d : 7;
}

inline std::int32_t add_wrap(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) + static_cast<std::uint32_t>(b));
}
inline std::int32_t mul_wrap(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
}

// A decoder over one layer; inactive when the layer is empty.
struct Layer {
  ByteSource src;
  ArithmeticDecoder dec;
  bool changed = false;

  bool overrun() const { return changed && dec.overrun(); }

  void start(ByteSource s, bool needed) {
    src = s;
    changed = src.remaining() > 0;
    if (changed && needed) dec.init(src);
  }
};

// The scanner-channel switch of the items after POINT14: makes `channel`
// current (a new context starts from the last values of the one left) and
// returns the context whose last values predict this point (see the top).
template <typename Context>
Context* switch_channel(std::unique_ptr<Context> (&contexts)[4], std::uint32_t& current,
                        std::uint32_t channel, bool v3) {
  Context* last = contexts[current].get();
  if (channel == current) return last;
  current = channel;
  if (!contexts[channel]) {
    contexts[channel] = std::make_unique<Context>(last->last);
    return contexts[channel].get();
  }
  return v3 ? last : contexts[channel].get();
}

template <typename T>
T& lazy(std::unique_ptr<T>& p, std::uint32_t symbols) {
  if (!p) p = std::make_unique<T>(symbols);
  return *p;
}

// The fields of a LAS 1.4 point record (formats 6-10, first 30 bytes).
struct Point14 {
  std::int32_t x, y, z;
  std::uint16_t intensity;
  std::uint32_t return_number, number_of_returns;
  std::uint32_t class_flags, scanner_channel, scan_direction, edge;
  std::uint8_t classification, user_data;
  std::int16_t scan_angle;
  std::uint16_t source;
  std::uint64_t gps_time;  // the bits of the double
  bool gps_time_change = false;

  void read(const unsigned char* p) {
    x = load<std::int32_t>(p);
    y = load<std::int32_t>(p + 4);
    z = load<std::int32_t>(p + 8);
    intensity = load<std::uint16_t>(p + 12);
    return_number = p[14] & 15;
    number_of_returns = p[14] >> 4;
    class_flags = p[15] & 15;
    scanner_channel = (p[15] >> 4) & 3;
    scan_direction = (p[15] >> 6) & 1;
    edge = p[15] >> 7;
    classification = p[16];
    user_data = p[17];
    scan_angle = load<std::int16_t>(p + 18);
    source = load<std::uint16_t>(p + 20);
    gps_time = load<std::uint64_t>(p + 22);
  }
  void write(unsigned char* p) const {
    store(p, x);
    store(p + 4, y);
    store(p + 8, z);
    store(p + 12, intensity);
    p[14] = static_cast<std::uint8_t>(return_number | (number_of_returns << 4));
    p[15] = static_cast<std::uint8_t>(class_flags | (scanner_channel << 4) | (scan_direction << 6) |
                                      (edge << 7));
    p[16] = classification;
    p[17] = user_data;
    store(p + 18, scan_angle);
    store(p + 20, source);
    store(p + 22, gps_time);
  }
};

constexpr int kMulti = 500;
constexpr int kMultiMinus = -10;
constexpr int kMultiCodeFull = kMulti - kMultiMinus + 1;  // 511
constexpr int kMultiTotal = kMulti - kMultiMinus + 5;     // 515

struct Point14Context {
  explicit Point14Context(const Point14& from) : last(from) {
    last.gps_time_change = false;
    for (auto& v : last_z) v = from.z;
    for (auto& v : last_intensity) v = from.intensity;
    gps[0] = from.gps_time;
  }

  Point14 last;
  SymbolModel changed_values[8] = {SymbolModel(128), SymbolModel(128), SymbolModel(128),
                                   SymbolModel(128), SymbolModel(128), SymbolModel(128),
                                   SymbolModel(128), SymbolModel(128)};
  SymbolModel scanner_channel{3};
  std::unique_ptr<SymbolModel> number_of_returns[16], return_number[16];
  SymbolModel return_number_gps_same{13};
  IntegerDecompressor ic_dx{32, 2}, ic_dy{32, 22}, ic_z{32, 20};
  std::unique_ptr<SymbolModel> classification[64], flags[64], user_data[64];
  IntegerDecompressor ic_intensity{16, 4}, ic_scan_angle{16, 2}, ic_source{16};
  SymbolModel gps_multi{kMultiTotal}, gps_0diff{5};
  IntegerDecompressor ic_gps{32, 9};

  StreamingMedian5 median_x[12], median_y[12];
  std::int32_t last_z[8];
  std::uint16_t last_intensity[8];
  std::uint64_t gps[4] = {0, 0, 0, 0};
  std::int32_t gps_diff[4] = {0, 0, 0, 0};
  int gps_extreme[4] = {0, 0, 0, 0};
  int gps_last = 0, gps_next = 0;
};

enum LayerId { kXY, kZ, kClass, kFlags, kIntensity, kAngle, kUser, kSource, kGps, kPointLayers };

class Point14Decoder {
 public:
  static constexpr int kLayers = kPointLayers;

  void start(const unsigned char* first, const std::uint32_t sizes[kLayers], ByteSource& src,
             bool more_points) {
    for (int i = 0; i < kLayers; ++i) layers_[i].start(src.take(sizes[i]), more_points);
    if (more_points && !layers_[kXY].changed) throw CorruptData("the chunk has no XY layer");
    Point14 p;
    p.read(first);
    current_ = p.scanner_channel;
    contexts_[current_] = std::make_unique<Point14Context>(p);
  }

  bool overrun() const {
    for (const Layer& l : layers_)
      if (l.overrun()) return true;
    return false;
  }

  /// True when the last decoded point switched the scanner channel.
  bool switched() const { return (changed_ & (1u << 6)) != 0; }

  /// Decodes the next point into out (30 bytes); returns its scanner channel.
  std::uint32_t decode(unsigned char* out) {
    Point14Context* c = contexts_[current_].get();
    ArithmeticDecoder& dxy = layers_[kXY].dec;
    {
      const Point14& l = c->last;
      std::uint32_t lpr = l.return_number == 1 ? 1 : 0;
      lpr += l.return_number >= l.number_of_returns ? 2 : 0;
      lpr += l.gps_time_change ? 4 : 0;
      const std::uint32_t changed = dxy.decode_symbol(c->changed_values[lpr]);
      if (changed & (1 << 6)) {
        const std::uint32_t diff = dxy.decode_symbol(c->scanner_channel);
        const std::uint32_t channel = (current_ + diff + 1) % 4;
        if (!contexts_[channel]) contexts_[channel] = std::make_unique<Point14Context>(c->last);
        current_ = channel;
        c = contexts_[current_].get();
        c->last.scanner_channel = channel;
      }
      changed_ = changed;
    }
    Point14& p = c->last;
    const bool source_change = changed_ & (1 << 5);
    const bool gps_change = changed_ & (1 << 4);
    const bool angle_change = changed_ & (1 << 3);
    const std::uint32_t last_n = p.number_of_returns, last_r = p.return_number;
    std::uint32_t n = last_n;
    if (changed_ & (1 << 2)) {
      n = dxy.decode_symbol(lazy(c->number_of_returns[last_n], 16));
      p.number_of_returns = n;
    }
    std::uint32_t r;
    switch (changed_ & 3) {
      case 0:
        r = last_r;
        break;
      case 1:
        r = (last_r + 1) % 16;
        break;
      case 2:
        r = (last_r + 15) % 16;
        break;
      default:
        if (gps_change) {
          r = dxy.decode_symbol(lazy(c->return_number[last_r], 16));
        } else {
          const std::uint32_t sym = dxy.decode_symbol(c->return_number_gps_same);
          r = (last_r + sym + 2) % 16;
        }
        break;
    }
    p.return_number = r;
    const std::uint32_t m = kReturnMap6[n][r];
    const std::uint32_t l = return_level8(n, r);
    std::uint32_t cpr = r == 1 ? 2 : 0;
    cpr += r >= n ? 1 : 0;

    const std::uint32_t idx = (m << 1) | (gps_change ? 1 : 0);
    std::int32_t diff = c->ic_dx.decompress(dxy, c->median_x[idx].get(), n == 1);
    p.x = add_wrap(p.x, diff);
    c->median_x[idx].add(diff);
    std::uint32_t kb = c->ic_dx.k();
    diff = c->ic_dy.decompress(dxy, c->median_y[idx].get(), (n == 1) + (kb < 20 ? (kb & ~1u) : 20));
    p.y = add_wrap(p.y, diff);
    c->median_y[idx].add(diff);

    if (layers_[kZ].changed) {
      kb = (c->ic_dx.k() + c->ic_dy.k()) / 2;
      p.z =
          c->ic_z.decompress(layers_[kZ].dec, c->last_z[l], (n == 1) + (kb < 18 ? (kb & ~1u) : 18));
      c->last_z[l] = p.z;
    }
    if (layers_[kClass].changed) {
      const std::uint32_t ccc = ((p.classification & 0x1Fu) << 1) + (cpr == 3 ? 1 : 0);
      p.classification = static_cast<std::uint8_t>(
          layers_[kClass].dec.decode_symbol(lazy(c->classification[ccc], 256)));
    }
    if (layers_[kFlags].changed) {
      const std::uint32_t last_flags = (p.edge << 5) | (p.scan_direction << 4) | p.class_flags;
      const std::uint32_t f = layers_[kFlags].dec.decode_symbol(lazy(c->flags[last_flags], 64));
      p.edge = (f >> 5) & 1;
      p.scan_direction = (f >> 4) & 1;
      p.class_flags = f & 0x0F;
    }
    if (layers_[kIntensity].changed) {
      const std::uint32_t i = (cpr << 1) | (gps_change ? 1 : 0);
      p.intensity = static_cast<std::uint16_t>(
          c->ic_intensity.decompress(layers_[kIntensity].dec, c->last_intensity[i], cpr));
      c->last_intensity[i] = p.intensity;
    }
    if (layers_[kAngle].changed && angle_change)
      p.scan_angle = static_cast<std::int16_t>(
          c->ic_scan_angle.decompress(layers_[kAngle].dec, p.scan_angle, gps_change ? 1 : 0));
    if (layers_[kUser].changed)
      p.user_data = static_cast<std::uint8_t>(
          layers_[kUser].dec.decode_symbol(lazy(c->user_data[p.user_data / 4], 256)));
    if (layers_[kSource].changed && source_change)
      p.source =
          static_cast<std::uint16_t>(c->ic_source.decompress(layers_[kSource].dec, p.source));
    if (layers_[kGps].changed && gps_change) {
      decode_gps(*c, layers_[kGps].dec);
      p.gps_time = c->gps[c->gps_last];
    }
    p.write(out);
    p.gps_time_change = gps_change;
    return current_;
  }

 private:
  static void decode_gps(Point14Context& c, ArithmeticDecoder& dec) {
    for (int guard = 0;; ++guard) {
      if (guard > 8) throw CorruptData("GPS time: endless sequence switches");
      int& last = c.gps_last;
      if (c.gps_diff[last] == 0) {
        const int multi = static_cast<int>(dec.decode_symbol(c.gps_0diff));
        if (multi == 0) {
          c.gps_diff[last] = c.ic_gps.decompress(dec, 0, 0);
          c.gps[last] += static_cast<std::uint64_t>(static_cast<std::int64_t>(c.gps_diff[last]));
          c.gps_extreme[last] = 0;
        } else if (multi == 1) {
          full_time(c, dec);
        } else {
          last = (last + multi - 1) & 3;
          continue;
        }
      } else {
        int multi = static_cast<int>(dec.decode_symbol(c.gps_multi));
        if (multi == 1) {
          c.gps[last] += static_cast<std::uint64_t>(
              static_cast<std::int64_t>(c.ic_gps.decompress(dec, c.gps_diff[last], 1)));
          c.gps_extreme[last] = 0;
        } else if (multi < kMultiCodeFull) {
          std::int32_t d;
          if (multi == 0) {
            d = c.ic_gps.decompress(dec, 0, 7);
            extreme(c, d);
          } else if (multi < kMulti) {
            d = c.ic_gps.decompress(dec, mul_wrap(multi, c.gps_diff[last]), multi < 10 ? 2 : 3);
          } else if (multi == kMulti) {
            d = c.ic_gps.decompress(dec, mul_wrap(kMulti, c.gps_diff[last]), 4);
            extreme(c, d);
          } else {
            multi = kMulti - multi;
            if (multi > kMultiMinus) {
              d = c.ic_gps.decompress(dec, mul_wrap(multi, c.gps_diff[last]), 5);
            } else {
              d = c.ic_gps.decompress(dec, mul_wrap(kMultiMinus, c.gps_diff[last]), 6);
              extreme(c, d);
            }
          }
          c.gps[last] += static_cast<std::uint64_t>(static_cast<std::int64_t>(d));
        } else if (multi == kMultiCodeFull) {
          full_time(c, dec);
        } else {
          last = (last + multi - kMultiCodeFull) & 3;
          continue;
        }
      }
      return;
    }
  }
  static void extreme(Point14Context& c, std::int32_t d) {
    if (++c.gps_extreme[c.gps_last] > 3) {
      c.gps_diff[c.gps_last] = d;
      c.gps_extreme[c.gps_last] = 0;
    }
  }
  static void full_time(Point14Context& c, ArithmeticDecoder& dec) {
    c.gps_next = (c.gps_next + 1) & 3;
    const std::uint32_t high = static_cast<std::uint32_t>(
        c.ic_gps.decompress(dec, static_cast<std::int32_t>(c.gps[c.gps_last] >> 32), 8));
    c.gps[c.gps_next] = (static_cast<std::uint64_t>(high) << 32) | dec.read_int();
    c.gps_last = c.gps_next;
    c.gps_diff[c.gps_last] = 0;
    c.gps_extreme[c.gps_last] = 0;
  }

  Layer layers_[kLayers];
  std::unique_ptr<Point14Context> contexts_[4];
  std::uint32_t current_ = 0;
  std::uint32_t changed_ = 0;
};

// RGB14 / RGBNIR14: a colour layer (and a NIR layer) per chunk, contexts per
// scanner channel.
class ColorDecoder {
 public:
  ColorDecoder(bool nir, std::uint16_t version) : nir_(nir), v3_(version == 3) {}
  int layers() const { return nir_ ? 2 : 1; }
  bool overrun() const { return rgb_.overrun() || nir_layer_.overrun(); }

  void start(const unsigned char* first, std::uint32_t channel, const std::uint32_t* sizes,
             ByteSource& src, bool more_points) {
    rgb_.start(src.take(sizes[0]), more_points);
    if (nir_) nir_layer_.start(src.take(sizes[1]), more_points);
    std::uint16_t last[4];
    for (int i = 0; i < 4; ++i)
      last[i] = i < (nir_ ? 4 : 3) ? load<std::uint16_t>(first + 2 * i) : 0;
    current_ = channel;
    contexts_[current_] = std::make_unique<Context>(last);
  }

  void decode(unsigned char* out, std::uint32_t channel) {
    std::uint16_t* last = switch_channel(contexts_, current_, channel, v3_)->last;
    Context& c = *contexts_[current_];
    if (rgb_.changed) {
      std::uint16_t v[3];
      decode_rgb(rgb_.dec, c.rgb, last, v);
      std::memcpy(last, v, sizeof v);
    }
    for (int i = 0; i < 3; ++i) store(out + 2 * i, last[i]);
    if (!nir_) return;
    if (nir_layer_.changed) {
      ArithmeticDecoder& d = nir_layer_.dec;
      const std::uint32_t sym = d.decode_symbol(c.nir_used);
      std::uint16_t v;
      if (sym & 1)
        v = fold_u8(static_cast<int>(d.decode_symbol(c.nir_diff[0])) + (last[3] & 255));
      else
        v = last[3] & 0xFF;
      if (sym & 2)
        v |= static_cast<std::uint16_t>(
            fold_u8(static_cast<int>(d.decode_symbol(c.nir_diff[1])) + (last[3] >> 8)) << 8);
      else
        v |= last[3] & 0xFF00;
      last[3] = v;
    }
    store(out + 6, last[3]);
  }

 private:
  struct Context {
    explicit Context(const std::uint16_t* from) { std::memcpy(last, from, sizeof last); }
    std::uint16_t last[4];
    RgbModels rgb;
    SymbolModel nir_used{4};
    SymbolModel nir_diff[2] = {SymbolModel(256), SymbolModel(256)};
  };
  bool nir_, v3_;
  Layer rgb_, nir_layer_;
  std::unique_ptr<Context> contexts_[4];
  std::uint32_t current_ = 0;
};

// WAVEPACKET14: one layer, contexts per scanner channel.
class WavepacketDecoder {
 public:
  explicit WavepacketDecoder(std::uint16_t version) : v3_(version == 3) {}
  bool overrun() const { return layer_.overrun(); }

  void start(const unsigned char* first, std::uint32_t channel, std::uint32_t size, ByteSource& src,
             bool more_points) {
    layer_.start(src.take(size), more_points);
    for (auto& c : contexts_) c.reset();
    current_ = channel;
    contexts_[current_] = std::make_unique<Context>(first);
  }

  void decode(unsigned char* out, std::uint32_t channel) {
    Context* last = switch_channel(contexts_, current_, channel, v3_);
    if (layer_.changed) {
      decode_wavepacket(layer_.dec, contexts_[current_]->models, last->last, out);
      std::memcpy(last->last, out, sizeof last->last);
    } else {  // no packet changes in this chunk: the first point's
      std::memcpy(out, last->last, sizeof last->last);
    }
  }

 private:
  struct Context {
    explicit Context(const unsigned char* from) { std::memcpy(last, from, sizeof last); }
    unsigned char last[29];
    WavepacketModels models;
  };
  bool v3_;
  Layer layer_;
  std::unique_ptr<Context> contexts_[4];
  std::uint32_t current_ = 0;
};

// BYTE14: one layer per extra byte.
class Byte14Decoder {
 public:
  Byte14Decoder(std::size_t n, std::uint16_t version) : n_(n), v3_(version == 3), layers_(n) {}
  int layers() const { return static_cast<int>(n_); }
  bool overrun() const {
    for (const Layer& l : layers_)
      if (l.overrun()) return true;
    return false;
  }

  void start(const unsigned char* first, std::uint32_t channel, const std::uint32_t* sizes,
             ByteSource& src, bool more_points) {
    for (std::size_t i = 0; i < n_; ++i) layers_[i].start(src.take(sizes[i]), more_points);
    current_ = channel;
    contexts_[current_] = std::make_unique<Context>(std::vector<unsigned char>(first, first + n_));
  }

  void decode(unsigned char* out, std::uint32_t channel) {
    std::vector<unsigned char>& last = switch_channel(contexts_, current_, channel, v3_)->last;
    Context& c = *contexts_[current_];
    for (std::size_t i = 0; i < n_; ++i) {
      if (layers_[i].changed)
        last[i] = fold_u8(last[i] + static_cast<int>(layers_[i].dec.decode_symbol(c.models[i])));
      out[i] = last[i];
    }
  }

 private:
  struct Context {
    explicit Context(const std::vector<unsigned char>& from) : last(from) {
      models.reserve(last.size());
      for (std::size_t i = 0; i < last.size(); ++i) models.emplace_back(256);
    }
    std::vector<unsigned char> last;
    std::vector<SymbolModel> models;
  };
  std::size_t n_;
  bool v3_;
  std::vector<Layer> layers_;
  std::unique_ptr<Context> contexts_[4];
  std::uint32_t current_ = 0;
};

class LayeredChunk final : public ChunkDecoder {
 public:
  LayeredChunk(const std::vector<Item>& items, ByteSource data, std::uint64_t points)
      : src_(data), items_(items), points_(points) {
    point_v3_ = !items_.empty() && items_[0].version == 3;
    for (const Item& it : items_) {
      record_length_ += it.size;
      if (it.type == kRgb14 || it.type == kRgbNir14)
        color_ = std::make_unique<ColorDecoder>(it.type == kRgbNir14, it.version);
      else if (it.type == kWavepacket14)
        wave_ = std::make_unique<WavepacketDecoder>(it.version);
      else if (it.type == kByte14)
        bytes_ = std::make_unique<Byte14Decoder>(it.size, it.version);
    }
  }

  void decode(unsigned char* dst, std::size_t n) override {
    for (std::size_t i = 0; i < n; ++i, dst += record_length_) {
      if (!started_) {
        start(dst);
        continue;
      }
      if (++decoded_ >= points_) throw CorruptData("more points requested than the chunk holds");
      std::uint32_t channel = point_.decode(dst);
      if (point_v3_ && !point_.switched()) channel = 0;  // see the top of the file
      std::size_t off = 30;
      for (std::size_t k = 1; k < items_.size(); ++k) {
        if (items_[k].type == kByte14)
          bytes_->decode(dst + off, channel);
        else if (items_[k].type == kWavepacket14)
          wave_->decode(dst + off, channel);
        else
          color_->decode(dst + off, channel);
        off += items_[k].size;
      }
    }
    if (point_.overrun() || (color_ && color_->overrun()) || (wave_ && wave_->overrun()) ||
        (bytes_ && bytes_->overrun()))
      throw CorruptData("compressed data ends early");
  }

 private:
  void start(unsigned char* dst) {
    started_ = true;
    src_.get_bytes(dst, record_length_);
    const std::uint32_t count = src_.get_u32le();
    if (count != points_)
      throw CorruptData("the chunk holds " + std::to_string(count) +
                        " points but the chunk table says " + std::to_string(points_));
    // layer sizes of all items, then the layers in the same order
    std::vector<std::uint32_t> sizes;
    for (const Item& it : items_) {
      const int k = it.type == kPoint14    ? Point14Decoder::kLayers
                    : it.type == kByte14   ? static_cast<int>(it.size)
                    : it.type == kRgbNir14 ? 2
                                           : 1;
      for (int j = 0; j < k; ++j) sizes.push_back(src_.get_u32le());
    }
    std::uint64_t total = 0;
    for (std::uint32_t s : sizes) total += s;
    if (total != src_.remaining())
      throw CorruptData("its layers hold " + std::to_string(total) + " bytes but the chunk " +
                        std::to_string(src_.remaining()) + " after the layer table");
    const bool more = points_ > 1;
    std::size_t s = 0, off = 0;
    std::uint32_t channel = 0;
    for (const Item& it : items_) {
      if (it.type == kPoint14) {
        point_.start(dst, sizes.data() + s, src_, more);
        channel = (dst[15] >> 4) & 3;
        s += Point14Decoder::kLayers;
      } else if (it.type == kByte14) {
        bytes_->start(dst + off, channel, sizes.data() + s, src_, more);
        s += it.size;
      } else if (it.type == kWavepacket14) {
        wave_->start(dst + off, channel, sizes[s], src_, more);
        s += 1;
      } else {
        color_->start(dst + off, channel, sizes.data() + s, src_, more);
        s += color_->layers();
      }
      off += it.size;
    }
  }

  ByteSource src_;
  std::vector<Item> items_;
  std::uint64_t points_;
  std::uint64_t decoded_ = 0;
  std::size_t record_length_ = 0;
  bool started_ = false;
  Point14Decoder point_;
  bool point_v3_ = false;
  std::unique_ptr<ColorDecoder> color_;
  std::unique_ptr<WavepacketDecoder> wave_;
  std::unique_ptr<Byte14Decoder> bytes_;
};

}  // namespace

std::unique_ptr<ChunkDecoder> make_layered_decoder(const std::vector<Item>& items, ByteSource data,
                                                   std::uint64_t points) {
  return std::make_unique<LayeredChunk>(items, data, points);
}

}  // namespace citylod::io::detail::laz
