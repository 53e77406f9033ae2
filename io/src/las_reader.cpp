// LAS 1.0-1.4 reader, point formats 0-10 (little endian). LAZ (LASzip, COPC
// included) is decoded by our own decoder (laz_decoder.hpp): same records,
// same points as the uncompressed twin.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "citylod/geo/wkt.hpp"
#include "laz_decoder.hpp"
#include "readers_internal.hpp"

namespace citylod::io::detail {
namespace {

template <typename T>
T le(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // x86/ARM little endian hosts only
  return v;
}

constexpr std::size_t kBaseRecord[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

std::string fixed_string(const unsigned char* p, std::size_t n) {
  std::string s(reinterpret_cast<const char*>(p), n);
  auto z = s.find('\0');
  if (z != std::string::npos) s.resize(z);
  while (!s.empty() && (s.back() == ' ')) s.pop_back();
  return s;
}

const char* unit_name(int code, double* metres) {
  switch (code) {
    case 9001:
      *metres = 1.0;
      return "metre";
    case 9002:
      *metres = 0.3048;
      return "foot";
    case 9003:
      *metres = 1200.0 / 3937.0;
      return "US survey foot";
    case 9036:
      *metres = 1000.0;
      return "kilometre";
    default:
      *metres = 0;
      return "";
  }
}

class LasReader final : public LasRecordReader {
 public:
  explicit LasReader(const std::string& path) : in_(path) {
    info_.path = path;
    info_.format = Format::las;
    info_.format_name = "LAS";
    info_.encoding = "binary";
    if (in_.size() == 0) in_.fail("empty file");
    parse_header();
  }

  std::size_t read(PointSet& b, std::size_t max_points) override {
    b.clear();
    std::uint64_t left = info_.point_count - points_read_;
    std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, max_points));
    if (n == 0) return 0;
    b.positions.resize(n);
    b.classes.resize(n);
    if (rgb_offset_ > 0) b.colors.resize(n);
    const std::size_t rl = info_.las_record_length;
    const std::size_t chunk = std::max<std::size_t>(1, (4u << 20) / rl);
    std::size_t i = 0;
    while (i < n) {
      std::size_t k = std::min(chunk, n - i);
      buf_.resize(k * rl);
      fetch(buf_.data(), k, points_read_ + i);
      for (std::size_t r = 0; r < k; ++r) decode(buf_.data() + r * rl, b, i + r);
      i += k;
    }
    points_read_ += n;
    return n;
  }

  std::size_t read_records(unsigned char* dst, std::size_t max_records) override {
    std::uint64_t left = info_.point_count - points_read_;
    std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, max_records));
    fetch(dst, n, points_read_);
    points_read_ += n;
    return n;
  }

  double progress() const override {
    return info_.point_count
               ? static_cast<double>(points_read_) / static_cast<double>(info_.point_count)
               : 1.0;
  }

 private:
  void decode(const unsigned char* p, PointSet& b, std::size_t i) {
    auto& q = b.positions[i];
    q[0] = le<std::int32_t>(p) * info_.scale[0] + info_.offset[0];
    q[1] = le<std::int32_t>(p + 4) * info_.scale[1] + info_.offset[1];
    q[2] = le<std::int32_t>(p + 8) * info_.scale[2] + info_.offset[2];
    b.classes[i] = extended_ ? p[16] : static_cast<std::uint8_t>(p[15] & 0x1F);
    if (rgb_offset_ > 0) {
      const unsigned char* c = p + rgb_offset_;
      for (int a = 0; a < 3; ++a) {
        std::uint16_t v = le<std::uint16_t>(c + 2 * a);
        b.colors[i][a] =
            static_cast<std::uint8_t>(rgb16_ ? v >> 8 : std::min<std::uint16_t>(v, 255));
      }
    }
  }

  // The next k raw records (LAS layout); `first` is the index of the first.
  void fetch(unsigned char* dst, std::size_t k, std::uint64_t first) {
    const std::size_t rl = info_.las_record_length;
    if (laz_) {
      if (laz_->read(dst, k) < k)
        in_.fail("LAZ point data ends after " + std::to_string(first) + " of " +
                 std::to_string(info_.point_count) + " points");
      return;
    }
    std::size_t got = in_.read_some(dst, k * rl);
    if (got < k * rl) truncated(first + got / rl);
  }

  [[noreturn]] void truncated(std::uint64_t holds) {
    in_.fail("truncated: header declares " + std::to_string(info_.point_count) +
             " points but the file holds only " + std::to_string(holds));
  }

  /// What the header says of the point data and the records after it.
  struct Layout {
    int minor = 0;                  ///< LAS 1.minor
    std::uint16_t header_size = 0;  ///< bytes
    std::uint32_t point_offset = 0;
    std::uint32_t n_vlr = 0;
    std::uint8_t pf_raw = 0;  ///< point format byte (compression bits included)
    int pf = 0;               ///< point format
    std::uint16_t record_length = 0;
    std::uint32_t legacy_count = 0;
    std::uint64_t count = 0;  ///< points
    std::uint64_t evlr_start = 0;
    std::uint32_t n_evlr = 0;
    std::uint64_t file = 0;  ///< file size
    std::uint64_t end = 0;   ///< where the point data ends (the first EVLR, or the file's end)
  };

  void parse_header() {
    unsigned char h[375] = {};
    std::size_t got = in_.read_some(h, sizeof h);
    Layout l = read_header_fields(h, got);
    read_point_format(l);
    read_scale_and_box(h);
    read_point_count(h, l);
    read_vlrs(l);
    // A LASzip-compressed file has the compression bits or the laszip VLR; a
    // file merely named .laz without either is read as LAS.
    if (info_.compressed && (l.pf_raw & 0xC0) == 0 && laz_vlr_.empty()) {
      info_.compressed = false;
      info_.format = Format::las;
      info_.format_name = "LAS";
    } else if (!laz_vlr_.empty() && !info_.compressed) {
      info_.compressed = true;
      info_.format = Format::laz;
      info_.format_name = "LAZ";
    }
    check_point_data_size(l);
    read_evlrs(l);
    finish_crs();
    in_.seek(l.point_offset);
    if (info_.compressed) open_laz(l);
    if (!info_.compressed && rgb_offset_ > 0) detect_rgb_depth(l.point_offset);
  }

  /// The signature, version, sizes and offsets of the header's first 227 bytes.
  Layout read_header_fields(const unsigned char* h, std::size_t got) {
    if (got < 4 || std::memcmp(h, "LASF", 4) != 0) in_.fail("not a LAS file (no LASF signature)");
    if (got < 227)
      in_.fail("truncated: LAS header is " + std::to_string(got) + " bytes, needs at least 227");
    const int major = h[24], minor = h[25];
    info_.version = std::to_string(major) + "." + std::to_string(minor);
    if (major != 1 || minor > 4) in_.fail("unsupported LAS version " + info_.version);
    Layout l;
    l.minor = minor;
    l.header_size = le<std::uint16_t>(h + 94);
    l.point_offset = le<std::uint32_t>(h + 96);
    l.n_vlr = le<std::uint32_t>(h + 100);
    l.pf_raw = h[104];
    l.record_length = le<std::uint16_t>(h + 105);
    l.legacy_count = le<std::uint32_t>(h + 107);
    info_.system_id = fixed_string(h + 26, 32);
    info_.generating_software = fixed_string(h + 58, 32);
    if (l.header_size < 227) in_.fail("bad LAS header size " + std::to_string(l.header_size));
    if (l.header_size > got)
      in_.fail("truncated: LAS header declares " + std::to_string(l.header_size) + " bytes");
    if (l.point_offset < l.header_size)
      in_.fail("bad LAS header: point data offset lies inside the header");
    return l;
  }

  /// Compression (by the format bits or the name), the point format and what its
  /// records hold.
  void read_point_format(Layout& l) {
    info_.compressed = (l.pf_raw & 0xC0) != 0 || extension_of(info_.path) == "laz";
    if (info_.compressed) {
      info_.format = Format::laz;
      info_.format_name = "LAZ";
    }
    const int pf = l.pf_raw & 0x3F;
    l.pf = pf;
    if (pf > 10) in_.fail("unsupported LAS point format " + std::to_string(pf));
    info_.las_point_format = pf;
    info_.las_record_length = l.record_length;
    if (l.record_length < kBaseRecord[pf])
      in_.fail("bad LAS header: point record length " + std::to_string(l.record_length) +
               " is smaller than the " + std::to_string(kBaseRecord[pf]) +
               " bytes of point format " + std::to_string(pf));
    extended_ = pf >= 6;
    if (pf == 2) rgb_offset_ = 20;
    if (pf == 3 || pf == 5) rgb_offset_ = 28;
    if (pf == 7 || pf == 8 || pf == 10) rgb_offset_ = 30;
    info_.has_classes = true;
    info_.has_colors = rgb_offset_ > 0;
    info_.extra_attributes = {"intensity", "return_number", "number_of_returns", "scan_angle",
                              "point_source_id"};
    if (pf != 0 && pf != 2) info_.extra_attributes.push_back("gps_time");
    if (pf == 8 || pf == 10) info_.extra_attributes.push_back("nir");
    if (pf == 4 || pf == 5 || pf == 9 || pf == 10) info_.extra_attributes.push_back("waveform");
    if (l.record_length > kBaseRecord[pf]) info_.extra_attributes.push_back("extra_bytes");
  }

  /// Scale, offset (finite, non-zero scale) and bounding box (finite).
  void read_scale_and_box(const unsigned char* h) {
    for (int a = 0; a < 3; ++a) {
      info_.scale[a] = le<double>(h + 131 + 8 * a);
      info_.offset[a] = le<double>(h + 155 + 8 * a);
      if (!std::isfinite(info_.scale[a]) || info_.scale[a] == 0.0)
        in_.fail("bad LAS header: scale factor " + std::to_string(info_.scale[a]) +
                 " is zero or not finite");
      if (!std::isfinite(info_.offset[a])) in_.fail("bad LAS header: offset is not finite");
    }
    info_.bbox.max = {le<double>(h + 179), le<double>(h + 195), le<double>(h + 211)};
    info_.bbox.min = {le<double>(h + 187), le<double>(h + 203), le<double>(h + 219)};
    info_.bbox_from_header = true;
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(info_.bbox.min[a]) || !std::isfinite(info_.bbox.max[a]))
        in_.fail("bad LAS header: bounding box is not finite");
  }

  /// The point count (LAS 1.4: the 64-bit one, which the legacy one must match when
  /// set) and where the EVLRs are.
  void read_point_count(const unsigned char* h, Layout& l) {
    l.count = l.legacy_count;
    if (l.minor >= 4 && l.header_size >= 375) {
      l.evlr_start = le<std::uint64_t>(h + 235);
      l.n_evlr = le<std::uint32_t>(h + 243);
      const std::uint64_t count64 = le<std::uint64_t>(h + 247);
      if (l.legacy_count != 0 && count64 != l.legacy_count)
        in_.fail("bad LAS header: legacy point count " + std::to_string(l.legacy_count) +
                 " and 64-bit point count " + std::to_string(count64) + " disagree");
      l.count = count64;
    }
    info_.point_count = l.count;
  }

  /// VLRs between the header and the point data.
  void read_vlrs(const Layout& l) {
    std::uint64_t pos = l.header_size;
    for (std::uint32_t i = 0; i < l.n_vlr; ++i) {
      if (pos + 54 > l.point_offset)
        in_.fail("bad LAS header: VLR #" + std::to_string(i) + " of " + std::to_string(l.n_vlr) +
                 " extends beyond the point data offset");
      unsigned char vh[54];
      in_.seek(pos);
      in_.read_exact(vh, 54, "a VLR header");
      const std::uint64_t len = le<std::uint16_t>(vh + 20);
      if (pos + 54 + len > l.point_offset)
        in_.fail("bad LAS header: VLR #" + std::to_string(i) +
                 " extends beyond the point data offset");
      handle_vlr(fixed_string(vh + 2, 16), le<std::uint16_t>(vh + 18), pos + 54, len);
      pos += 54 + len;
    }
  }

  /// Point data size against the file size, before anything is allocated.
  void check_point_data_size(Layout& l) {
    l.file = in_.size();
    l.end = l.file;
    if (l.evlr_start != 0 && l.n_evlr > 0 && l.evlr_start <= l.file) l.end = l.evlr_start;
    const std::uint64_t avail = l.end > l.point_offset ? l.end - l.point_offset : 0;
    if (info_.compressed) return;
    if (l.count > avail / l.record_length) truncated(avail / l.record_length);
    const int pf = l.pf;
    const bool waveform =
        pf == 4 || pf == 5 || pf == 9 || pf == 10;  // packets may follow the points
    if (l.n_evlr == 0 && !waveform && avail / l.record_length > l.count)
      in_.fail("header declares " + std::to_string(l.count) + " points but the file holds " +
               std::to_string(avail / l.record_length) + " (header point count is wrong)");
  }

  /// EVLRs (LAS 1.4).
  void read_evlrs(const Layout& l) {
    std::uint64_t e = l.evlr_start;
    for (std::uint32_t i = 0; i < l.n_evlr; ++i) {
      if (e < l.point_offset || e + 60 > l.file)
        in_.fail("bad LAS header: EVLR #" + std::to_string(i) + " lies outside the file");
      unsigned char eh[60];
      in_.seek(e);
      in_.read_exact(eh, 60, "an EVLR header");
      const std::uint64_t len = le<std::uint64_t>(eh + 20);
      if (len > l.file - e - 60)
        in_.fail("bad LAS header: EVLR #" + std::to_string(i) + " extends beyond the file");
      handle_vlr(fixed_string(eh + 2, 16), le<std::uint16_t>(eh + 18), e + 60, len);
      e += 60 + len;
    }
  }

  /// The LAZ decoder of the point data (and the colour depth from its first points).
  void open_laz(const Layout& l) {
    if (laz_vlr_.empty())
      in_.fail("bad LAZ: the compressed file has no laszip VLR (\"laszip encoded\", 22204)");
    laz_source_.path = info_.path;
    laz_source_.vlr = laz_vlr_;
    laz_source_.point_offset = l.point_offset;
    laz_source_.data_end = l.end;
    laz_source_.file_size = l.file;
    laz_source_.point_count = l.count;
    laz_source_.record_length = l.record_length;
    laz_source_.point_format = l.pf;
    if (rgb_offset_ > 0) {
      LazStream first(laz_source_, 1);
      detect_rgb_depth_laz(first);
    }
    laz_ = std::make_unique<LazStream>(laz_source_, default_laz_threads());
  }

  void detect_rgb_depth_laz(LazStream& s) {
    const std::size_t rl = info_.las_record_length;
    std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(info_.point_count, 4096));
    std::vector<unsigned char> tmp(n * rl);
    std::size_t got = s.read(tmp.data(), n);
    rgb16_ = false;
    for (std::size_t r = 0; r < got; ++r)
      for (int a = 0; a < 3; ++a)
        if (le<std::uint16_t>(tmp.data() + r * rl + rgb_offset_ + 2 * a) > 255) rgb16_ = true;
  }

  // 8-bit colours stored unscaled in the 16-bit fields are common: look at
  // the first points to decide whether to shift.
  void detect_rgb_depth(std::uint64_t point_offset) {
    const std::size_t rl = info_.las_record_length;
    std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(info_.point_count, 4096));
    std::vector<unsigned char> tmp(n * rl);
    std::size_t got = in_.read_some(tmp.data(), tmp.size());
    rgb16_ = false;
    for (std::size_t r = 0; r + 1 <= got / rl; ++r)
      for (int a = 0; a < 3; ++a)
        if (le<std::uint16_t>(tmp.data() + r * rl + rgb_offset_ + 2 * a) > 255) rgb16_ = true;
    in_.seek(point_offset);
  }

  void handle_vlr(const std::string& user, std::uint16_t id, std::uint64_t data,
                  std::uint64_t len) {
    if (user == "laszip encoded" && id == 22204 && len > 0 && len < (1u << 16)) {
      laz_vlr_.resize(static_cast<std::size_t>(len));
      in_.seek(data);
      in_.read_exact(laz_vlr_.data(), laz_vlr_.size(), "the laszip VLR");
      return;
    }
    if (user != "LASF_Projection" || len == 0 || len > (64u << 20)) return;
    std::vector<unsigned char> d(static_cast<std::size_t>(len));
    in_.seek(data);
    in_.read_exact(d.data(), d.size(), "a VLR");
    if (id == 2112) {
      wkt_ = fixed_string(d.data(), d.size());
    } else if (id == 34735 && d.size() >= 8) {
      const std::size_t nkeys = le<std::uint16_t>(d.data() + 6);
      for (std::size_t k = 0; k < nkeys && 8 + 8 * k + 8 <= d.size(); ++k) {
        const unsigned char* e = d.data() + 8 + 8 * k;
        const std::uint16_t key = le<std::uint16_t>(e), loc = le<std::uint16_t>(e + 2);
        const std::uint16_t value = le<std::uint16_t>(e + 6);
        if (loc != 0) continue;  // value stored elsewhere (double/ascii params)
        if (key == 3072) projected_ = value;
        if (key == 2048) geographic_ = value;
        if (key == 3076) linear_units_ = value;
        if (key == 4099) vertical_units_ = value;
        if (key == 4096) vertical_cs_ = value;
      }
    } else if (id == 34737) {
      citation_ = fixed_string(d.data(), d.size());
    }
  }

  void finish_crs() {
    info_.crs_wkt = wkt_;
    const geo::WktSummary w = geo::summarize_wkt(wkt_);
    info_.crs_name = w.name;
    if (projected_ > 0 && projected_ < 32767)
      info_.epsg = projected_;
    else if (projected_ == 0 && geographic_ > 0 && geographic_ < 32767)
      info_.epsg = geographic_;
    if (info_.epsg == 0) info_.epsg = w.epsg;
    if (vertical_cs_ > 0 && vertical_cs_ < 32767) info_.vertical_epsg = vertical_cs_;
    if (info_.vertical_epsg == 0) info_.vertical_epsg = w.vertical_epsg;
    double m = 0;
    const char* u = unit_name(linear_units_, &m);
    if (*u) {
      info_.linear_unit = u;
      info_.linear_unit_m = m;
    } else if (!w.unit.empty()) {
      info_.linear_unit = w.unit;
      info_.linear_unit_m = w.unit_m;
    }
    u = unit_name(vertical_units_, &m);
    if (*u) {
      info_.vertical_unit = u;
      info_.vertical_unit_m = m;
    }
    if (info_.crs_name.empty() && !citation_.empty()) {
      std::string c = citation_;
      auto bar = c.find('|');
      if (bar != std::string::npos) c.resize(bar);
      info_.crs_name = c;
    }
  }

  InputFile in_;
  std::vector<unsigned char> laz_vlr_;
  LazSource laz_source_;
  std::unique_ptr<LazStream> laz_;
  bool extended_ = false;
  std::size_t rgb_offset_ = 0;
  bool rgb16_ = true;
  std::vector<unsigned char> buf_;
  std::string wkt_, citation_;
  int projected_ = 0, geographic_ = 0, linear_units_ = 0, vertical_units_ = 0, vertical_cs_ = 0;
};

}  // namespace

std::unique_ptr<ReaderBase> open_las(const std::string& path) {
  return std::make_unique<LasReader>(path);
}

std::unique_ptr<LasRecordReader> open_las_records(const std::string& path) {
  return std::make_unique<LasReader>(path);
}

}  // namespace citylod::io::detail
