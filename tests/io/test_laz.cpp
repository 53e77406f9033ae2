// LAZ / COPC decoding: the published digests of the shared files, LAZ against
// its LAS twin through the normal reader API, truncated and corrupted files,
// and known-answer tests of the arithmetic decoder.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <tuple>

#include "citylod/io/reader.hpp"
#include "citylod/io/verify.hpp"
#include "fixtures.hpp"
#include "laz_arithmetic.hpp"
#include "laz_decoder.hpp"
#include "support/las_read.hpp"

using namespace citylod::io;
using namespace citylod::io::test;
namespace laz = citylod::io::detail::laz;

namespace {

// Decodes everything; returns "" or the IoError message. Any other exception fails.
std::string try_verify(const std::string& p) {
  try {
    verify_point_records(p);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

void expect_same_points(const PointSet& a, const PointSet& b) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.classes.size(), b.classes.size());
  ASSERT_EQ(a.colors.size(), b.colors.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.positions[i], b.positions[i]) << "point " << i;
    if (!a.classes.empty()) {
      ASSERT_EQ(a.classes[i], b.classes[i]) << "point " << i;
    }
    if (!a.colors.empty()) {
      ASSERT_EQ(a.colors[i], b.colors[i]) << "point " << i;
    }
  }
}

}  // namespace

// ------------------------------------------------------------ published digests
struct Digest {
  const char* file;
  std::uint64_t count;
  int point_format;
  const char* sha256;
};

class LazDigest : public ::testing::TestWithParam<Digest> {};

TEST_P(LazDigest, MatchesPublishedSha256) {
  const Digest& d = GetParam();
  const std::string p = shared(d.file);
  CITYLOD_REQUIRE_SHARED(p);
  PointRecordDigest r = verify_point_records(p);
  EXPECT_TRUE(r.compressed);
  EXPECT_EQ(r.count, d.count);
  EXPECT_EQ(r.point_format, d.point_format);
  EXPECT_EQ(r.sha256, d.sha256);
  FileInfo h = read_header(p);
  // the decoded coordinates lie in the header's box (header rounding aside)
  for (int a = 0; a < 3; ++a) {
    EXPECT_GE(r.bbox.min[a], h.bbox.min[a] - h.scale[a]);
    EXPECT_LE(r.bbox.max[a], h.bbox.max[a] + h.scale[a]);
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, LazDigest,
    ::testing::Values(Digest{"laz/simple.laz", 1065, 3,
                             "0717948a72e6bf719db8d96ded1e76b760d73fb683347ebe3dd603832e3d5015"},
                      Digest{"laz/autzen_trim.laz", 110000, 3,
                             "f4eb6d80bf1fa507ffdcdaa73606d09041982659a50ee3895957e0b2b347f54b"},
                      Digest{"laz/lone-star.copc.laz", 518862, 6,
                             "fb81e03fca9a6e3569feb6aa6e9eb92ddbca58ac10cb29fc8ba5e7eec4027dd3"},
                      Digest{"laz/1.2-with-color.copc.laz", 1065, 7,
                             "361eda6829430490b1bba3a2665408642d16211f6c349b2f11edf451c8164422"}));

// ------------------------------------------------------------ LAZ vs LAS twins
class LazTwin : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(LazTwin, SameRecordsAndSamePoints) {
  const std::string laz_path = shared(GetParam().first), las_path = shared(GetParam().second);
  CITYLOD_REQUIRE_SHARED(laz_path);
  CITYLOD_REQUIRE_SHARED(las_path);
  PointRecordDigest a = verify_point_records(laz_path), b = verify_point_records(las_path);
  EXPECT_TRUE(a.compressed);
  EXPECT_FALSE(b.compressed);
  EXPECT_EQ(a.count, b.count);
  EXPECT_EQ(a.sha256, b.sha256);
  EXPECT_EQ(a.bbox.min, b.bbox.min);
  EXPECT_EQ(a.bbox.max, b.bbox.max);

  // the normal reader API, in small uneven batches (crossing chunk borders)
  auto ra = PointReader::open(laz_path), rb = PointReader::open(las_path);
  EXPECT_EQ(ra->info().has_colors, rb->info().has_colors);
  PointSet x, y;
  std::size_t total = 0;
  for (std::size_t batch = 777;; batch = batch * 3 % 20011 + 1) {
    const std::size_t n = ra->read(x, batch);
    ASSERT_EQ(rb->read(y, batch), n);
    if (n == 0) break;
    expect_same_points(x, y);
    total += n;
  }
  EXPECT_EQ(total, a.count);

  FileInfo sa = scan_file(laz_path), sb = scan_file(las_path);
  EXPECT_TRUE(sa.scanned);
  EXPECT_EQ(sa.point_count, sb.point_count);
  EXPECT_EQ(sa.class_counts, sb.class_counts);
  EXPECT_EQ(sa.bbox.min, sb.bbox.min);
  EXPECT_EQ(sa.bbox.max, sb.bbox.max);
}

INSTANTIATE_TEST_SUITE_P(
    SharedData, LazTwin,
    ::testing::Values(std::make_pair("delft/ahn3_cropped_2.laz", "delft/ahn3_cropped_2.las"),
                      std::make_pair("laz/simple.laz", "laz/simple.las"),
                      std::make_pair("laz/autzen_trim.laz", "las/autzen_trim.las")));

TEST(Laz, CopcHoldsTheSamePointsAsItsLas12Twin) {
  // COPC stores the points in octree order, as point format 7: compare as sets.
  const std::string c = shared("laz/1.2-with-color.copc.laz"), l = shared("laz/1.2-with-color.las");
  CITYLOD_REQUIRE_SHARED(c);
  CITYLOD_REQUIRE_SHARED(l);
  PointSet a = read_points(c), b = read_points(l);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_TRUE(a.has_colors());
  // (the two files have other offsets: compare the coordinates in centimetres)
  auto key = [](const PointSet& s) {
    std::vector<std::tuple<long long, long long, long long, int, Rgb8>> k;
    for (std::size_t i = 0; i < s.size(); ++i)
      k.emplace_back(std::llround(s.positions[i][0] * 100), std::llround(s.positions[i][1] * 100),
                     std::llround(s.positions[i][2] * 100), s.classes[i], s.colors[i]);
    std::sort(k.begin(), k.end());
    return k;
  };
  EXPECT_EQ(key(a), key(b));
}

TEST(Laz, ParallelAndSequentialDecodingAgree) {
  for (const char* f : {"delft/ahn3_cropped_2.laz", "laz/lone-star.copc.laz"}) {
    const std::string p = shared(f);
    CITYLOD_REQUIRE_SHARED(p);
    FileInfo h = read_header(p);
    std::vector<unsigned char> vlr;
    // the LazStream is private: rebuild its source from the file
    const auto las = citylod::test::read_las(p);
    ASSERT_TRUE(las);
    const citylod::test::LasVlr* laszip = las->vlr("laszip encoded", 22204);
    ASSERT_TRUE(laszip);
    vlr.assign(laszip->payload.begin(), laszip->payload.end());
    ASSERT_FALSE(vlr.empty());
    citylod::io::detail::LazSource src;
    src.path = p;
    src.vlr = vlr;
    src.point_offset = las->point_offset;
    src.file_size = src.data_end = las->bytes.size();
    src.point_count = h.point_count;
    src.record_length = h.las_record_length;
    src.point_format = h.las_point_format;
    citylod::io::detail::LazStream one(src, 1), three(src, 3);
    EXPECT_NE(three.description().find("chunks"), std::string::npos);
    std::vector<unsigned char> a(h.point_count * h.las_record_length), b(a.size());
    std::size_t got = 0;
    while (got < h.point_count) {
      const std::size_t n = one.read(a.data() + got * h.las_record_length, 10007);
      ASSERT_GT(n, 0u);
      got += n;
    }
    EXPECT_EQ(three.read(b.data(), h.point_count + 5), h.point_count);
    EXPECT_EQ(three.read(b.data(), 1), 0u);
    EXPECT_TRUE(a == b) << f;
  }
}

// ------------------------------------------------------------ bad input
TEST(LazBadInput, TruncatedFilesFailClearly) {
  for (const char* f : {"delft/ahn3_cropped_2.laz", "laz/lone-star.copc.laz", "laz/simple.laz"}) {
    const std::string p = shared(f);
    CITYLOD_REQUIRE_SHARED(p);
    const std::string s = read_file(p);
    const std::uint32_t offset = get<std::uint32_t>(s, 96);
    for (double frac : {0.0, 0.001, 0.3, 0.5, 0.9, 0.99, 0.9999}) {
      const std::size_t cut = offset + static_cast<std::size_t>(frac * (s.size() - offset));
      const std::string t = write_file("trunc.laz", s.substr(0, cut));
      const std::string w = try_verify(t);
      EXPECT_NE(w, "") << f << " cut at " << cut;
      EXPECT_NE(w.find(t), std::string::npos) << w;
      // the chunk table, a chunk, or the EVLRs behind the points (COPC) are missing
      EXPECT_TRUE(w.find("chunk") != std::string::npos || w.find("EVLR") != std::string::npos) << w;
    }
  }
}

TEST(LazBadInput, FlippedBytesInChunkDataNeverCrash) {
  for (const char* f : {"delft/ahn3_cropped_2.laz", "laz/autzen_trim.laz", "laz/lone-star.copc.laz",
                        "laz/1.2-with-color.copc.laz"}) {
    const std::string p = shared(f);
    CITYLOD_REQUIRE_SHARED(p);
    const std::string s = read_file(p);
    const std::uint32_t offset = get<std::uint32_t>(s, 96);
    const std::uint64_t table = get<std::uint64_t>(s, offset);
    int detected = 0, tries = 0;
    const bool big = s.size() > 2000000;  // lone-star: fewer flips (each decodes 518k points)
    for (std::uint64_t at = offset + 8 + 3; at < table;
         at += (table - offset) / (big ? 5 : 11) + 1) {
      std::string t = s;
      t[at] = static_cast<char>(t[at] ^ 0x5A);
      const std::string path = write_file("flip.laz", t);
      const std::string w = try_verify(path);
      ++tries;
      if (!w.empty()) {
        ++detected;
        EXPECT_NE(w.find(path), std::string::npos) << w;
        EXPECT_NE(w.find("chunk"), std::string::npos) << w;
      }
    }
    EXPECT_GE(tries, 5);
    // point-wise chunks must be consumed exactly: flips there are caught
    if (std::string(f).find("copc") == std::string::npos) {
      EXPECT_GT(detected, tries / 2) << f;
    }
  }
}

TEST(LazBadInput, LyingChunkTable) {
  const std::string p = shared("delft/ahn3_cropped_2.laz");
  CITYLOD_REQUIRE_SHARED(p);
  const std::string s = read_file(p);
  const std::uint32_t offset = get<std::uint32_t>(s, 96);
  const std::uint64_t table = get<std::uint64_t>(s, offset);

  std::string t = s;
  put<std::uint32_t>(t, table + 4, 6);  // 6 chunks for 208432 points in chunks of 50000
  expect_io_error([&] { read_header(write_file("lie1.laz", t)); }, "lists 6 chunks");
  t = s;
  put<std::uint32_t>(t, table + 4, 0xFFFFFFF0u);
  expect_io_error([&] { read_header(write_file("lie2.laz", t)); }, "chunk table");
  t = s;
  put<std::uint64_t>(t, offset, s.size() + 100);
  expect_io_error([&] { read_header(write_file("lie3.laz", t)); }, "lies outside the file");
  t = s;
  put<std::uint32_t>(t, table, 7);
  expect_io_error([&] { read_header(write_file("lie4.laz", t)); }, "chunk table version 7");
  // the coded byte sizes: every flip gives a clear error
  for (std::size_t k = 8; k < s.size() - table; ++k) {
    t = s;
    t[table + k] = static_cast<char>(t[table + k] ^ 0x21);
    const std::string path = write_file("lie5.laz", t);
    const std::string w = try_verify(path);
    if (w.empty()) continue;  // a flip in the coder's padding may change nothing
    EXPECT_NE(w.find("chunk"), std::string::npos) << w;
  }

  // variable chunks (COPC): the point counts are in the table
  const std::string c = shared("laz/lone-star.copc.laz");
  CITYLOD_REQUIRE_SHARED(c);
  const std::string cs = read_file(c);
  const std::uint32_t coff = get<std::uint32_t>(cs, 96);
  const std::uint64_t ctable = get<std::uint64_t>(cs, coff);
  int detected = 0;
  for (std::size_t k = 8; k < 40; ++k) {
    t = cs;
    t[ctable + k] = static_cast<char>(t[ctable + k] ^ 0x10);
    const std::string path = write_file("lie6.laz", t);
    const std::string w = try_verify(path);
    if (w.empty()) continue;
    ++detected;
    EXPECT_NE(w.find("chunk"), std::string::npos) << w;
  }
  EXPECT_GT(detected, 20);
}

TEST(LazBadInput, LayerTableAndPointCountOfALayeredChunk) {
  const std::string p = shared("laz/lone-star.copc.laz");
  CITYLOD_REQUIRE_SHARED(p);
  const std::string s = read_file(p);
  const std::uint32_t offset = get<std::uint32_t>(s, 96);
  const std::size_t chunk0 = offset + 8;
  std::string t = s;
  put<std::uint32_t>(t, chunk0 + 30, get<std::uint32_t>(s, chunk0 + 30) + 1);  // point count
  expect_io_error([&] { verify_point_records(write_file("layer1.laz", t)); }, "chunk 0 of 15");
  t = s;
  put<std::uint32_t>(t, chunk0 + 34, get<std::uint32_t>(s, chunk0 + 34) + 9);  // XY layer size
  expect_io_error([&] { verify_point_records(write_file("layer2.laz", t)); }, "layers hold");
  t = s;
  put<std::uint32_t>(t, chunk0 + 34, 0xFFFFFFF0u);
  expect_io_error([&] { verify_point_records(write_file("layer3.laz", t)); }, "chunk 0 of 15");
}

TEST(LazBadInput, UnsupportedItemsAreRefusedClearly) {
  const std::string p = shared("laz/simple.laz");
  CITYLOD_REQUIRE_SHARED(p);
  const std::string s = read_file(p);
  const std::size_t vlr = get<std::uint16_t>(s, 94) + 54;  // the only VLR: laszip
  ASSERT_EQ(get<std::uint16_t>(s, vlr - 54 + 18), 22204);
  std::string t = s;
  put<std::uint16_t>(t, vlr + 34 + 6 * 1 + 4, 1);  // GPSTIME11 v1
  expect_io_error([&] { read_header(write_file("v1.laz", t)); }, "GPSTIME11 v1");
  t = s;
  put<std::uint16_t>(t, vlr + 34 + 6 * 2, 9);  // RGB12 -> WAVEPACKET13 (v1 of 29 bytes only)
  expect_io_error([&] { read_header(write_file("wave.laz", t)); }, "WAVEPACKET13 v2 of size 6");
  t = s;
  put<std::uint16_t>(t, vlr, 1);  // unchunked compressor
  expect_io_error([&] { read_header(write_file("pointwise.laz", t)); }, "unchunked");
  t = s;
  put<std::uint16_t>(t, vlr + 34 + 6 * 2 + 2, 8);  // RGB12 of 8 bytes
  expect_io_error([&] { read_header(write_file("size.laz", t)); }, "36-byte records");
}

// ------------------------------------------------------------ arithmetic decoder
TEST(LazArithmetic, KnownAnswers) {
  {
    // value 0: every decision takes the lowest interval
    const unsigned char z[16] = {};
    laz::ByteSource src(z, sizeof z);
    laz::ArithmeticDecoder d;
    d.init(src);
    laz::BitModel bit;
    laz::SymbolModel small(5), big(256);
    EXPECT_EQ(d.decode_bit(bit), 0u);
    EXPECT_EQ(d.decode_symbol(small), 0u);
    EXPECT_EQ(d.decode_symbol(big), 0u);
    laz::IntegerDecompressor ic(32, 2);
    EXPECT_EQ(ic.decompress(d, 1234567, 1), 1234567);  // k = 0, corrector bit 0
    EXPECT_EQ(ic.k(), 0u);
  }
  {
    // value just below the length: the highest interval
    const unsigned char f[16] = {0xFF, 0xFF, 0xFF, 0xFE, 0xFF, 0xFF, 0xFF, 0xFF,
                                 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
    laz::ByteSource src(f, sizeof f);
    laz::ArithmeticDecoder d;
    d.init(src);
    laz::BitModel bit;
    laz::SymbolModel small(5), big(256);
    EXPECT_EQ(d.decode_bit(bit), 1u);
    EXPECT_EQ(d.decode_symbol(small), 4u);
    EXPECT_EQ(d.decode_symbol(big), 255u);
  }
  {
    // raw bits: 0x80000000 / (0xFFFFFFFF >> 8) = 128
    const unsigned char r[8] = {0x80, 0, 0, 0, 0, 0, 0, 0};
    laz::ByteSource src(r, sizeof r);
    laz::ArithmeticDecoder d;
    d.init(src);
    EXPECT_EQ(d.read_bits(8), 128u);
  }
  {
    const unsigned char bad[4] = {0xFF, 0xFF, 0xFF, 0xFF};
    laz::ByteSource src(bad, sizeof bad);
    laz::ArithmeticDecoder d;
    EXPECT_THROW(d.init(src), laz::CorruptData);
    laz::ByteSource empty(bad, 3);
    EXPECT_THROW(d.init(empty), laz::CorruptData);
  }
  {
    // a stream that ends: reading on shifts in zeros and flags the overrun
    // (the chunk decoders turn it into an error) instead of running past the buffer
    const unsigned char z[5] = {};
    laz::ByteSource src(z, sizeof z);
    laz::ArithmeticDecoder d;
    d.init(src);
    EXPECT_FALSE(d.overrun());
    for (int i = 0; i < 100; ++i) d.read_bits(16);
    EXPECT_TRUE(d.overrun());
    EXPECT_EQ(d.remaining(), 0u);
  }
  {
    // the decoder table is only a shortcut: every symbol of a skewed model
    // decodes to the symbol whose interval holds the value, as a search over
    // the distribution finds it
    laz::SymbolModel m(40);
    for (int i = 0; i < 3000; ++i) {
      ++m.symbol_count[i % 7 == 0 ? 39 : (i % 3 == 0 ? 5 : 0)];
      if (--m.symbols_until_update == 0) m.update();
    }
    for (std::uint32_t v = 0; v < (1u << 15); v += 7) {
      std::uint32_t want = 0;
      while (want + 1 < m.symbols && m.distribution[want + 1] <= v) ++want;
      std::uint32_t t = v >> m.table_shift;
      std::uint32_t lo = m.decoder_table[t], hi = m.decoder_table[t + 1];
      ASSERT_LE(lo, want) << v;
      ASSERT_GE(hi, want) << v;
    }
  }
}

TEST(LazArithmetic, StreamingMedian) {
  laz::StreamingMedian5 m;
  EXPECT_EQ(m.get(), 0);
  for (int v : {5, 1, 9, 7, 3}) m.add(v);
  EXPECT_EQ(m.get(), 5);
  for (int v : {100, 100, 100}) m.add(v);
  EXPECT_EQ(m.get(), 100);
}

TEST(Sha256, KnownAnswers) {
  EXPECT_EQ(sha256_hex("", 0), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc", 3),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  const std::string m = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  EXPECT_EQ(sha256_hex(m.data(), m.size()),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Verify, PlainLasFromFixture) {
  LasSpec s;
  for (int i = 0; i < 7; ++i) s.points.push_back({1000.0 + i, 2000.0 - i, 3.0 + i, 2});
  const std::string bytes = make_las(s);
  const std::string p = write_file("verify.las", bytes);
  PointRecordDigest d = verify_point_records(p);
  EXPECT_FALSE(d.compressed);
  EXPECT_EQ(d.count, 7u);
  const std::uint32_t off = get<std::uint32_t>(bytes, 96);
  EXPECT_EQ(d.sha256, sha256_hex(bytes.data() + off, 7 * d.record_length));
  expect_io_error([&] { verify_point_records(write_file("v.xyz", "1 2 3\n")); }, "not a LAS");
}
