// LAZ waveform packets (point formats 4, 5, 9, 10): the packet decoder on a
// known stream, garbage where a packet stream should be (shared data, CI), and
// on the optional extra data (CITYLOD_EXTRA_DATA/laz, see its README): LAZ
// files written by LASzip against their LAS twins, the public fullwave.laz
// (format 10) against the physics of its packets, truncated and flipped files.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <set>

#include "citylod/io/reader.hpp"
#include "citylod/io/verify.hpp"
#include "fixtures.hpp"
#include "laz_chunk.hpp"
#include "laz_decoder.hpp"
#include "support/las_read.hpp"

using namespace citylod::io;
using namespace citylod::io::test;
namespace laz = citylod::io::detail::laz;

namespace {

std::string try_verify(const std::string& p) {
  try {
    verify_point_records(p);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

// The payload of the VLR (user id, record id) of a LAS file's bytes, or "".
std::string vlr_payload(const std::string& s, const char* user, std::uint16_t record) {
  const auto las = citylod::test::parse_las(s);
  const citylod::test::LasVlr* v = las ? las->vlr(user, record) : nullptr;
  return v ? v->payload : "";
}

// All decoded records of a LAZ file, through the private stream.
std::vector<unsigned char> decode_all(const std::string& p, FileInfo& h) {
  h = read_header(p);
  const std::string s = read_file(p);
  const std::string v = vlr_payload(s, "laszip encoded", 22204);
  citylod::io::detail::LazSource src;
  src.path = p;
  src.vlr.assign(v.begin(), v.end());
  src.point_offset = get<std::uint32_t>(s, 96);
  src.file_size = src.data_end = s.size();
  src.point_count = h.point_count;
  src.record_length = h.las_record_length;
  src.point_format = h.las_point_format;
  citylod::io::detail::LazStream stream(src, 2);
  std::vector<unsigned char> r(h.point_count * h.las_record_length);
  EXPECT_EQ(stream.read(r.data(), h.point_count), h.point_count);
  return r;
}

}  // namespace

// ------------------------------------------------------------ no data needed
TEST(LazWave, PacketDecoderKnownAnswerOnAZeroStream) {
  // a stream of zeros decodes every symbol as 0 and every corrector as 0:
  // descriptor 0, "same offset", and size, return point, dx, dy, dz as predicted
  const unsigned char z[64] = {};
  laz::ByteSource src(z, sizeof z);
  laz::ArithmeticDecoder d;
  d.init(src);
  laz::WavepacketModels m;
  unsigned char last[29], out[29];
  for (int i = 0; i < 29; ++i) last[i] = static_cast<unsigned char>(7 * i + 3);
  for (int round = 0; round < 3; ++round) {
    std::memset(out, 0xEE, sizeof out);
    laz::decode_wavepacket(d, m, last, out);
    EXPECT_EQ(out[0], 0);
    EXPECT_EQ(std::memcmp(out + 1, last + 1, 28), 0) << "round " << round;
    EXPECT_EQ(m.last_offset_sym, 0u);
    std::memcpy(last, out, sizeof last);
  }
  EXPECT_FALSE(d.overrun());
}

// A point-wise chunk whose waveform items are not waveform data (simple.laz
// relabelled as format 4: POINT10, GPSTIME11, WAVEPACKET13): one clear error
// naming file and chunk.
TEST(LazWave, GarbageWhereThePacketsShouldBeFailsClearly) {
  {
    const std::string p = shared("laz/simple.laz");
    CITYLOD_REQUIRE_SHARED(p);
    std::string t = read_file(p);
    const std::size_t vlr = get<std::uint16_t>(t, 94) + 54;  // the only VLR: laszip
    ASSERT_EQ(get<std::uint16_t>(t, vlr - 54 + 18), 22204);
    ASSERT_EQ(get<std::uint16_t>(t, vlr + 34 + 6 * 2), 8);  // RGB12 -> WAVEPACKET13 v1
    put<std::uint16_t>(t, vlr + 34 + 6 * 2, 9);
    put<std::uint16_t>(t, vlr + 34 + 6 * 2 + 2, 29);
    put<std::uint16_t>(t, vlr + 34 + 6 * 2 + 4, 1);
    t[104] = static_cast<char>((t[104] & 0xC0) | 4);
    put<std::uint16_t>(t, 105, 57);
    const std::string path = write_file("wave-garbage4.laz", t);
    EXPECT_EQ(read_header(path).las_point_format, 4);
    const std::string w = expect_io_error([&] { verify_point_records(path); }, "chunk 0 of 1");
    EXPECT_NE(w.find(path), std::string::npos) << w;
  }
}

// ------------------------------------------------------------ extra data
struct WaveTwin {
  const char* name;  // CITYLOD_EXTRA_DATA/laz/oracle/<name>.laz and .las
  int point_format;
  std::uint16_t item_version;  // of the waveform (or last) item
};

class LazWaveTwin : public ::testing::TestWithParam<WaveTwin> {};

TEST_P(LazWaveTwin, SameRecordsAsTheLasTwin) {
  const WaveTwin& t = GetParam();
  const std::string laz_path = extra(std::string("laz/oracle/") + t.name + ".laz");
  const std::string las_path = extra(std::string("laz/oracle/") + t.name + ".las");
  if (!std::filesystem::exists(laz_path) || !std::filesystem::exists(las_path))
    GTEST_SKIP() << "extra data missing: " << laz_path;
  const std::string v = vlr_payload(read_file(laz_path), "laszip encoded", 22204);
  ASSERT_GE(v.size(), 40u);
  const std::uint16_t n = get<std::uint16_t>(v, 32);
  EXPECT_EQ(get<std::uint16_t>(v, 34 + 6 * (n - 1) + 4), t.item_version);
  const PointRecordDigest a = verify_point_records(laz_path);
  const PointRecordDigest b = verify_point_records(las_path);
  EXPECT_TRUE(a.compressed);
  EXPECT_FALSE(b.compressed);
  EXPECT_EQ(a.point_format, t.point_format);
  EXPECT_EQ(b.point_format, t.point_format);
  EXPECT_EQ(a.count, 10750u);
  EXPECT_EQ(a.count, b.count);
  EXPECT_EQ(a.sha256, b.sha256);
}

INSTANTIATE_TEST_SUITE_P(ExtraData, LazWaveTwin,
                         ::testing::Values(WaveTwin{"pf4", 4, 1}, WaveTwin{"pf4_tweak", 4, 1},
                                           WaveTwin{"pf5_tweak", 5, 1}, WaveTwin{"pf9_ch", 9, 3},
                                           WaveTwin{"pf9_ch_plain", 9, 3},
                                           WaveTwin{"pf10_ch", 10, 3}, WaveTwin{"pf9_v4_14", 9, 4},
                                           WaveTwin{"pf10_ch_v4_14", 10, 4},
                                           WaveTwin{"pf6_ch", 6, 3}, WaveTwin{"pf7_ch_eb", 7, 3}),
                         [](const ::testing::TestParamInfo<WaveTwin>& i) {
                           return std::string(i.param.name);
                         });

// fullwave.laz (laspy's test data, YellowScan, format 10, no LAS twin): the
// packets must agree with the waveform descriptor and with the points.
TEST(LazWave, FullwaveLazPacketsAgreeWithDescriptorAndPoints) {
  const std::string p = extra("laz/fullwave.laz");
  if (!std::filesystem::exists(p)) GTEST_SKIP() << "extra data missing: " << p;
  const PointRecordDigest d = verify_point_records(p);
  EXPECT_EQ(d.point_format, 10);
  EXPECT_EQ(d.count, 10750u);
  EXPECT_EQ(d.sha256, "b49cab16bf6befbbc8f00653bda3b288883b82c5c6ef91018252210338ab9f02");

  const std::string wpd = vlr_payload(read_file(p), "LASF_Spec", 100);  // descriptor 1
  ASSERT_EQ(wpd.size(), 26u);
  const std::uint32_t packet_bytes =
      static_cast<std::uint8_t>(wpd[0]) / 8 * get<std::uint32_t>(wpd, 2);  // 16 bit x 2484
  FileInfo h;
  const std::vector<unsigned char> r = decode_all(p, h);
  ASSERT_EQ(h.las_record_length, 67u);
  struct Pulse {
    std::vector<const unsigned char*> points;
  };
  std::map<std::uint64_t, Pulse> pulses;
  for (std::size_t i = 0; i < h.point_count; ++i) {
    const unsigned char* q = &r[i * 67];
    const unsigned char* w = q + 38;
    ASSERT_EQ(w[0], 1) << "point " << i;  // descriptor index
    ASSERT_EQ(laz::load<std::uint32_t>(w + 9), packet_bytes) << "point " << i;
    const std::uint64_t off = laz::load<std::uint64_t>(w + 1);
    ASSERT_EQ((off - 60) % packet_bytes, 0u) << "point " << i;  // behind the 60-byte EVLR header
    // the direction is light's path per picosecond (about c / 2, two-way)
    const double n =
        std::hypot(laz::load<float>(w + 17), laz::load<float>(w + 21), laz::load<float>(w + 25));
    ASSERT_GT(n, 1.40e-4) << "point " << i;
    ASSERT_LT(n, 1.52e-4) << "point " << i;
    pulses[off].points.push_back(q);
  }
  // the packets are stored one after the other, one per pulse
  EXPECT_EQ(pulses.rbegin()->first, 60 + (pulses.size() - 1) * packet_bytes);
  // every return of a pulse maps back to one anchor: point + return point * (dx, dy, dz)
  std::size_t multi = 0, incomplete = 0;
  double worst = 0;
  for (const auto& [off, pulse] : pulses) {
    std::set<int> returns;
    double anchor0[3] = {0, 0, 0};
    for (std::size_t k = 0; k < pulse.points.size(); ++k) {
      const unsigned char* q = pulse.points[k];
      returns.insert(q[14] & 15);
      if ((q[14] >> 4) != static_cast<int>(pulse.points.size())) ++incomplete;
      EXPECT_EQ(laz::load<double>(q + 22), laz::load<double>(pulse.points[0] + 22))
          << "pulse at " << off;
      const float t = laz::load<float>(q + 38 + 13);
      for (int a = 0; a < 3; ++a) {
        const double x = laz::load<std::int32_t>(q + 4 * a) * h.scale[a] + h.offset[a] +
                         static_cast<double>(t) * laz::load<float>(q + 38 + 17 + 4 * a);
        if (k == 0)
          anchor0[a] = x;
        else
          worst = std::max(worst, std::abs(x - anchor0[a]));
      }
    }
    EXPECT_EQ(returns.size(), pulse.points.size());
    EXPECT_EQ(*returns.begin(), 1);
    if (pulse.points.size() > 1) ++multi;
  }
  EXPECT_EQ(pulses.size(), 7124u);
  EXPECT_EQ(incomplete, 1u);  // the last pulse: 1 of its 3 returns is in the file
  EXPECT_GT(multi, 1900u);
  EXPECT_LE(worst, 0.0015);  // the coordinates' 1 mm resolution
}

TEST(LazWave, TruncatedAndFlippedWaveformFilesFailClearly) {
  int files = 0;
  for (const char* f : {"laz/fullwave.laz", "laz/oracle/pf4_tweak.laz", "laz/oracle/pf5_tweak.laz",
                        "laz/oracle/pf9_ch.laz"}) {
    const std::string p = extra(f);
    if (!std::filesystem::exists(p)) continue;
    ++files;
    const std::string s = read_file(p);
    const std::uint32_t offset = get<std::uint32_t>(s, 96);
    for (double frac : {0.0, 0.3, 0.6, 0.9, 0.999}) {
      const std::size_t cut = offset + static_cast<std::size_t>(frac * (s.size() - offset));
      const std::string t = write_file("wave-trunc.laz", s.substr(0, cut));
      const std::string w = try_verify(t);
      EXPECT_NE(w.find(t), std::string::npos) << f << " cut at " << cut << ": " << w;
      EXPECT_NE(w.find("chunk"), std::string::npos) << w;
      EXPECT_EQ(w.find('\n'), std::string::npos) << w;
    }
    const std::uint64_t table = get<std::uint64_t>(s, offset);
    int detected = 0, tries = 0;
    for (std::uint64_t at = offset + 8 + 70; at < table; at += (table - offset) / 9 + 1) {
      std::string t = s;
      t[at] = static_cast<char>(t[at] ^ 0x5A);
      const std::string path = write_file("wave-flip.laz", t);
      const std::string w = try_verify(path);
      ++tries;
      if (!w.empty()) {
        ++detected;
        EXPECT_NE(w.find("chunk"), std::string::npos) << w;
      }
    }
    EXPECT_GE(tries, 5);
    if (std::string(f).find("pf4") != std::string::npos) {
      EXPECT_GT(detected, tries / 2) << f;  // point-wise chunks are consumed exactly
    }
  }
  if (files == 0) GTEST_SKIP() << "extra data missing: " << extra("laz");
}
