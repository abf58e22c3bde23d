// Tests of the sample file reader/writers (src/validate/sample_io.h): round trips, every accepted text and
// NPY variant, and every error path (each message must name the file and the line or row).
#include "validate/sample_io.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_sample_io {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

// A fresh directory per test, removed afterwards.
class SampleIo : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("microsim_sample_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path file(const std::string& name) const { return dir_ / name; }
  fs::path write_bytes(const std::string& name, const std::string& bytes) const {
    const fs::path p = file(name);
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }
  // Expects read_direction_samples to throw a SampleFileError whose message contains the file name and
  // every one of `fragments`.
  void expect_error(const fs::path& p, std::initializer_list<std::string> fragments) const {
    try {
      read_direction_samples(p);
      ADD_FAILURE() << "no error for " << p;
    } catch (const SampleFileError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(p.string()), std::string::npos) << "message does not name the file: " << msg;
      for (const std::string& f : fragments)
        EXPECT_NE(msg.find(f), std::string::npos) << "message lacks '" << f << "': " << msg;
    }
  }
  fs::path dir_;
};

std::vector<Vec3<double>> random_unit_vectors(int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  std::vector<Vec3<double>> v;
  while (static_cast<int>(v.size()) < n) {
    const Vec3<double> w(g(rng), g(rng), g(rng));
    if (w.norm() > 1e-3) v.push_back(w.normalized());
  }
  // Awkward values: poles, axes, a horizon direction, tiny components.
  v.push_back({0, 0, 1});
  v.push_back({0, 0, -1});
  v.push_back({1, 0, 0});
  v.push_back(Vec3<double>(1e-300, -1e-17, 1).normalized());
  return v;
}

void append_le(std::string& s, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

// An NPY file: magic, version, header (padded to 64 bytes with a final '\n' unless `pad` is false),
// and the raw data.
std::string npy_bytes(int major, int minor, const std::string& dict, const std::string& data, bool pad = true) {
  std::string header = dict;
  const std::size_t prefix = 8 + (major == 1 ? 2 : 4);
  if (pad) {
    const std::size_t total = (prefix + header.size() + 1 + 63) / 64 * 64;
    header.append(total - prefix - header.size() - 1, ' ');
    header.push_back('\n');
  }
  std::string out = "\x93NUMPY";
  out.push_back(static_cast<char>(major));
  out.push_back(static_cast<char>(minor));
  append_le(out, header.size(), major == 1 ? 2 : 4);
  return out + header + data;
}

std::string f8_data(std::initializer_list<double> values) {
  std::string s;
  for (double v : values) append_le(s, std::bit_cast<std::uint64_t>(v), 8);
  return s;
}
std::string f4_data(std::initializer_list<float> values) {
  std::string s;
  for (float v : values) append_le(s, std::bit_cast<std::uint32_t>(v), 4);
  return s;
}

std::string dict(const std::string& descr, const std::string& shape, const std::string& order = "False") {
  return "{'descr': '" + descr + "', 'fortran_order': " + order + ", 'shape': " + shape + ", }";
}

}  // namespace

// ---- round trips ----------------------------------------------------------------------------------------

TEST_F(SampleIo, NpyFloat64RoundTripIsExactUpToRenormalisation) {
  const auto v = random_unit_vectors(1000, 1);
  write_npy(file("a.npy"), v, /*as_float32=*/false);
  const auto r = read_direction_samples(file("a.npy"));
  ASSERT_EQ(r.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i) EXPECT_LE((r[i] - v[i]).norm(), 4e-16) << i;
  EXPECT_FALSE(fs::exists(file("a.npy.partial")));
  // The header ends on a 64-byte boundary as the NPY spec asks.
  EXPECT_EQ((fs::file_size(file("a.npy")) - v.size() * 24) % 64, 0u);
}

TEST_F(SampleIo, NpyFloat32RoundTripWithinFloatRounding) {
  const auto v = random_unit_vectors(1000, 2);
  write_npy(file("a.npy"), v, /*as_float32=*/true);
  EXPECT_EQ((fs::file_size(file("a.npy")) - v.size() * 12) % 64, 0u);
  const auto r = read_direction_samples(file("a.npy"));
  ASSERT_EQ(r.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    EXPECT_LE((r[i] - v[i]).norm(), 2e-7) << i;  // float32 rounding: <= 2^-24 relative per component
    EXPECT_NEAR(r[i].norm(), 1.0, 1e-15);        // renormalised in double
  }
}

TEST_F(SampleIo, TextRoundTripIsExactUpToRenormalisation) {
  const auto v = random_unit_vectors(1000, 3);
  write_text_samples(file("a.txt"), v);
  const auto r = read_direction_samples(file("a.txt"));
  ASSERT_EQ(r.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i) EXPECT_LE((r[i] - v[i]).norm(), 4e-16) << i;
  EXPECT_FALSE(fs::exists(file("a.txt.partial")));
}

TEST_F(SampleIo, WriterReplacesAnExistingFileAndFailsCleanlyOnABadDirectory) {
  const auto v = random_unit_vectors(5, 4);
  write_text_samples(file("a.txt"), v);
  write_text_samples(file("a.txt"), std::span(v).first(2));
  EXPECT_EQ(read_direction_samples(file("a.txt")).size(), 2u);
  EXPECT_THROW(write_npy(file("missing_dir/a.npy"), v, false), SampleFileError);
  EXPECT_THROW(write_text_samples(file("missing_dir/a.txt"), v), SampleFileError);
  EXPECT_FALSE(fs::exists(file("missing_dir")));
}

// ---- accepted text variants -----------------------------------------------------------------------------

TEST_F(SampleIo, TextAcceptsSeparatorsCommentsBlankLinesCrlfAndBom) {
  const std::string text =
      "\xEF\xBB\xBF# header comment\n"
      "\n"
      "0 0 1\n"
      "   \t  \n"
      "0,0,1\n"
      "0 , 0 ,\t1   # trailing comment\n"
      "+0.6\t-0.8 0\r\n"
      "6e-1, 8E-1, 0.0\n"
      "# 1 2 3  (a commented-out line is not data)\n"
      "-1 0 -0"; // no final newline
  const auto r = read_direction_samples(write_bytes("a.txt", text));
  ASSERT_EQ(r.size(), 6u);
  EXPECT_EQ(r[0], Vec3<double>(0, 0, 1));
  EXPECT_EQ(r[1], Vec3<double>(0, 0, 1));
  EXPECT_EQ(r[2], Vec3<double>(0, 0, 1));
  EXPECT_NEAR((r[3] - Vec3<double>(0.6, -0.8, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((r[4] - Vec3<double>(0.6, 0.8, 0)).norm(), 0.0, 1e-15);
  EXPECT_EQ(r[5], Vec3<double>(-1, 0, 0));
}

TEST_F(SampleIo, TextUnitToleranceIsOneInTenThousand) {
  // 4 printed decimals: |w| - 1 = 5e-5 is accepted and renormalised; 2e-4 is rejected.
  const auto ok = read_direction_samples(write_bytes("ok.txt", "0 0 1.00005\n"));
  EXPECT_EQ(ok[0], Vec3<double>(0, 0, 1));
  expect_error(write_bytes("bad.txt", "0 0 1\n0 0 1.0002\n"), {"line 2", "length", "1e-4"});
}

// ---- text errors ----------------------------------------------------------------------------------------

TEST_F(SampleIo, TextErrorsNameTheLine) {
  expect_error(write_bytes("word.txt", "0 0 1\n0 abc 1\n"), {"line 2", "malformed", "'abc'"});
  expect_error(write_bytes("header.txt", "x y z\n0 0 1\n"), {"line 1", "malformed", "'x'"});
  expect_error(write_bytes("glued.txt", "0 0 1\n\n0 0 1x\n"), {"line 3", "'1x'"});
  expect_error(write_bytes("twodots.txt", "0 0 1.0.0\n"), {"line 1", "'1.0.0'"});
  expect_error(write_bytes("two.txt", "# c\n0 1\n"), {"line 2", "column count", "found 2"});
  expect_error(write_bytes("four.txt", "0 0 1\n0 0 1 0\n"), {"line 2", "column count", "found 4"});
  expect_error(write_bytes("doublecomma.txt", "0,,0,1\n"), {"line 1", "empty field"});
  expect_error(write_bytes("leadcomma.txt", ",0,0,1\n"), {"line 1", "empty field"});
  expect_error(write_bytes("trailcomma.txt", "0 0 1\n0,0,1,\n"), {"line 2", "trailing comma"});
  expect_error(write_bytes("huge.txt", "0 0 1\n1e999 0 0\n"), {"line 2", "out of the range"});
  expect_error(write_bytes("short.txt", "0 0 1\n0.5 0 0\n"), {"line 2", "length 0.5", "not unit length"});
  expect_error(write_bytes("halfvec.txt", "0.6 0.8 1\n"), {"line 1", "not unit length"});
}

// Non-finite values (as printf spells them) and the zero vector are the sampler's failures, not a
// malformed file: NaN rows, counted, the first kListed named.
TEST_F(SampleIo, SamplerFailuresAreNanRowsNamedByLineOrRow) {
  DirectionSampleReader text(write_bytes("nan.txt", "0 0 1\nnan 0 1\n0 0 1\n-nan 0 1\ninf 0 0\n0 0 0\n"
                                                    "0 -inf 1\n0 0 -nan\n0 0 1\n"));
  std::vector<Vec3<double>> rows(16);
  ASSERT_EQ(text.read(rows), 9u);
  EXPECT_TRUE(rows[0].allFinite());
  for (int i : {1, 3, 4, 5, 6, 7}) EXPECT_TRUE(rows[std::size_t(i)].array().isNaN().all()) << "row " << i;
  EXPECT_EQ(rows[8], Vec3<double>(0, 0, 1));
  EXPECT_EQ(text.invalid_rows().count, 6u);
  EXPECT_EQ(text.invalid_rows().first, (std::vector<std::string>{"line 2", "line 4", "line 5", "line 6", "line 7"}));
  EXPECT_EQ(text.storage(), "text");

  const double nan = std::numeric_limits<double>::quiet_NaN();
  DirectionSampleReader npy(write_bytes("nan.npy", npy_bytes(1, 0, dict("<f4", "(3, 3)"), f4_data({0, 0, 1, 0, 0, 0, float(nan), 0, 1}))));
  ASSERT_EQ(npy.read(rows), 3u);
  EXPECT_EQ(npy.invalid_rows().count, 2u);
  EXPECT_EQ(npy.invalid_rows().first, (std::vector<std::string>{"row 1 (0-based)", "row 2 (0-based)"}));
  EXPECT_EQ(npy.storage(), "float32 .npy");
  EXPECT_EQ(DirectionSampleReader(write_bytes("f8.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 0, 1})))).storage(),
            "float64 .npy");
}

TEST_F(SampleIo, EmptyInputsAreErrors) {
  expect_error(write_bytes("empty.txt", ""), {"empty"});
  expect_error(write_bytes("comments.txt", "# nothing\n\n  # here\n"), {"empty", "no samples"});
  expect_error(write_bytes("empty.npy", npy_bytes(1, 0, dict("<f8", "(0, 3)"), "")), {"empty", "0 rows"});
  expect_error(file("does_not_exist.txt"), {"cannot open"});
  expect_error(dir_, {"directory"});
}

// ---- accepted NPY variants ------------------------------------------------------------------------------

TEST_F(SampleIo, NpyVersions2And3AndHeaderSpellingsAreAccepted) {
  const std::string d = f8_data({0, 0, 1, 0.6, 0, -0.8});
  for (int major : {1, 2, 3}) {
    const std::string name = std::to_string(major) + "v.npy";
    const auto r = read_direction_samples(write_bytes(name, npy_bytes(major, 0, dict("<f8", "(2, 3)"), d)));
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r[1], Vec3<double>(0.6, 0, -0.8));
  }
  // Key order, double quotes, no trailing comma, Python 2 'L' suffixes, no padding: all valid dicts
  // (the terminating newline is required: see NpyHeaderWithoutNewlineIsRejected).
  const std::string odd = "{\"shape\": (2L, 3L), \"fortran_order\": False, \"descr\": \"<f8\"}\n";
  EXPECT_EQ(read_direction_samples(write_bytes("odd.npy", npy_bytes(1, 0, odd, d, /*pad=*/false))).size(), 2u);
  // A file named .txt with NPY content is read as NPY (detection is by the magic string).
  EXPECT_EQ(read_direction_samples(write_bytes("npy.txt", npy_bytes(1, 0, dict("<f8", "(2,3)"), d))).size(), 2u);
}

TEST_F(SampleIo, NpyUnitTolerancesDependOnThePrecision) {
  // float32: 5e-6 off is accepted (GPU rsqrt), 5e-5 off is rejected.
  const auto ok32 = read_direction_samples(
      write_bytes("ok32.npy", npy_bytes(1, 0, dict("<f4", "(1, 3)"), f4_data({0, 0, 1.000005f}))));
  EXPECT_EQ(ok32[0], Vec3<double>(0, 0, 1));
  expect_error(write_bytes("bad32.npy", npy_bytes(1, 0, dict("<f4", "(2, 3)"), f4_data({0, 0, 1, 0, 0, 1.00005f}))),
               {"row 1", "not unit length", "float32"});
  // float64: 5e-7 off is accepted, 5e-6 off is rejected.
  EXPECT_EQ(read_direction_samples(
                write_bytes("ok64.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 0, 1.0000005}))))
                .size(),
            1u);
  expect_error(write_bytes("bad64.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 1.000005, 0}))),
               {"row 0", "not unit length", "float64"});
}

// ---- NPY errors -----------------------------------------------------------------------------------------

TEST_F(SampleIo, NpyDataErrorsNameTheRow) {
  expect_error(write_bytes("short.npy", npy_bytes(1, 0, dict("<f8", "(2, 3)"), f8_data({0, 0, 1, 0, 0, 0.5}))),
               {"row 1", "not unit length"});
  // Truncated in the middle of row 1 (0-based) of 3.
  expect_error(write_bytes("trunc.npy", npy_bytes(1, 0, dict("<f8", "(3, 3)"), f8_data({0, 0, 1, 0}))),
               {"truncated", "row 1", "3 rows"});
  expect_error(write_bytes("trunc0.npy", npy_bytes(1, 0, dict("<f4", "(2, 3)"), "")), {"truncated", "row 0"});
  expect_error(write_bytes("trailing.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 0, 1, 0}))),
               {"trailing bytes"});
}

TEST_F(SampleIo, NpyHeaderErrors) {
  const std::string d = f8_data({0, 0, 1});
  expect_error(write_bytes("v4.npy", npy_bytes(4, 0, dict("<f8", "(1, 3)"), d)), {"version 4.0"});
  expect_error(write_bytes("v11.npy", npy_bytes(1, 1, dict("<f8", "(1, 3)"), d)), {"version 1.1"});
  expect_error(write_bytes("be_int.npy", npy_bytes(1, 0, dict(">i8", "(1, 3)"), d)), {"dtype '>i8'"});
  expect_error(write_bytes("bar.npy", npy_bytes(1, 0, dict("|f8", "(1, 3)"), d)), {"dtype '|f8'"});
  expect_error(write_bytes("int.npy", npy_bytes(1, 0, dict("<i8", "(1, 3)"), d)), {"dtype '<i8'"});
  expect_error(write_bytes("half.npy", npy_bytes(1, 0, dict("<f2", "(1, 3)"), d)), {"dtype '<f2'"});
  expect_error(write_bytes("struct.npy",
                           npy_bytes(1, 0, "{'descr': [('x', '<f8')], 'fortran_order': False, 'shape': (1,), }", d)),
               {"structured"});
  expect_error(write_bytes("badbool.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)", "0"), d)), {"True or False"});
  expect_error(write_bytes("1d.npy", npy_bytes(1, 0, dict("<f8", "(3,)"), d)), {"shape (3,)", "(N, 3)"});
  expect_error(write_bytes("n4.npy", npy_bytes(1, 0, dict("<f8", "(1, 4)"), d)), {"shape (1, 4)"});
  expect_error(write_bytes("3d.npy", npy_bytes(1, 0, dict("<f8", "(1, 3, 1)"), d)), {"shape (1, 3, 1)"});
  expect_error(write_bytes("neg.npy", npy_bytes(1, 0, dict("<f8", "(-1, 3)"), d)), {"non-negative integers"});
  expect_error(write_bytes("nokey.npy", npy_bytes(1, 0, "{'descr': '<f8', 'shape': (1, 3), }", d)), {"lacks"});
  expect_error(write_bytes("extrakey.npy",
                           npy_bytes(1, 0, "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 3), 'x': 1}", d)),
               {"unexpected key 'x'"});
  expect_error(write_bytes("nobrace.npy", npy_bytes(1, 0, "'descr': '<f8'", d)), {"NPY header", "'{'"});
  expect_error(write_bytes("junk.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)") + " junk", d)), {"after the header"});
  // Cut inside the version field, the length field and the header itself.
  expect_error(write_bytes("cut1.npy", std::string("\x93NUMPY\x01", 7)), {"truncated"});
  expect_error(write_bytes("cut2.npy", std::string("\x93NUMPY\x01\x00\x76", 9)), {"truncated"});
  expect_error(write_bytes("cut3.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), d).substr(0, 30)),
               {"truncated NPY header"});
  expect_error(write_bytes("fake.npy", "0 0 1\n"), {"not an NPY file"});
  // np.savez's archive (a zip's local file header first): named as such, not read as malformed text.
  expect_error(write_bytes("samples.npz", std::string("PK\x03\x04\x14\x00\x00\x00", 8) + "a.npy"),
               {"a zip archive (numpy's .npz", "np.save"});
}

// ---- files written by NumPy itself (tests/data/README.md says how) --------------------------------------

namespace {
const fs::path kData = MICROSIM_TEST_DATA;
const std::vector<Vec3<double>> kFixtureRows = {{0, 0, 1}, {0.6, 0, 0.8}, {0, -0.6, 0.8}, {0.48, 0.64, 0.6}, {-1, 0, 0}};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
}  // namespace

TEST_F(SampleIo, ReadsFilesWrittenByNumpy) {
  for (const char* name : {"npy_samples_f8.npy", "npy_samples_f8_v2.npy", "npy_samples_fortran.npy",
                           "npy_samples_f8_be_fortran.npy", "text_samples_numpy.txt"}) {
    const auto r = read_direction_samples(kData / name);
    ASSERT_EQ(r.size(), kFixtureRows.size()) << name;
    for (std::size_t i = 0; i < r.size(); ++i) EXPECT_LE((r[i] - kFixtureRows[i]).norm(), 4e-16) << name << i;
  }
  for (const char* name : {"npy_samples_f4.npy", "npy_samples_f4_v3.npy", "npy_samples_f4_be.npy"}) {
    const auto r = read_direction_samples(kData / name);
    ASSERT_EQ(r.size(), kFixtureRows.size()) << name;
    for (std::size_t i = 0; i < r.size(); ++i) EXPECT_LE((r[i] - kFixtureRows[i]).norm(), 2e-7) << name << i;
  }
  expect_error(kData / "npy_samples_int.npy", {"dtype '<i8'"});
}

TEST_F(SampleIo, WriterOutputIsByteIdenticalToNumpySave) {
  write_npy(file("f8.npy"), kFixtureRows, /*as_float32=*/false);
  write_npy(file("f4.npy"), kFixtureRows, /*as_float32=*/true);
  EXPECT_EQ(slurp(file("f8.npy")), slurp(kData / "npy_samples_f8.npy"));
  EXPECT_EQ(slurp(file("f4.npy")), slurp(kData / "npy_samples_f4.npy"));
}

// ---- Fortran order (np.save of a transposed or column-indexed array) ---------------------------------------

namespace {

// The data of an (N, k) array of `rows` (each k values) in C order (row by row) or Fortran order (column by
// column), as float32 or float64.
std::string array_data(const std::vector<std::vector<double>>& rows, bool fortran, bool as_float32) {
  std::string s;
  const auto put = [&](double v) {
    if (as_float32) append_le(s, std::bit_cast<std::uint32_t>(float(v)), 4);
    else append_le(s, std::bit_cast<std::uint64_t>(v), 8);
  };
  const std::size_t k = rows.front().size();
  if (!fortran)
    for (const auto& row : rows)
      for (const double v : row) put(v);
  for (std::size_t c = 0; fortran && c < k; ++c)
    for (const auto& row : rows) put(row[c]);
  return s;
}

// n rows of x, y, z (a unit vector), pdf, weight.
std::vector<std::vector<double>> five_column_rows(int n, unsigned seed) {
  std::vector<std::vector<double>> rows;
  for (const Vec3<double>& w : random_unit_vectors(n, seed))
    rows.push_back({w.x(), w.y(), w.z(), 1.0 + w.x() * w.x(), 0.5 + 0.25 * w.z()});
  return rows;
}

struct ReadRows {
  std::vector<Vec3<double>> directions;
  std::vector<double> pdfs, weights;
};

// Every row of `path` read through the block reader in blocks of `block` rows.
ReadRows read_all(const fs::path& path, const SampleColumns& columns, std::size_t block) {
  DirectionSampleReader reader(path, columns);
  ReadRows all;
  std::vector<Vec3<double>> d(block);
  std::vector<double> pdfs(columns.has_pdf() ? block : 0), weights(block * std::size_t(columns.channels()));
  while (const std::size_t n = reader.read(d, pdfs, weights)) {
    all.directions.insert(all.directions.end(), d.begin(), d.begin() + std::ptrdiff_t(n));
    if (columns.has_pdf()) all.pdfs.insert(all.pdfs.end(), pdfs.begin(), pdfs.begin() + std::ptrdiff_t(n));
    all.weights.insert(all.weights.end(), weights.begin(), weights.begin() + std::ptrdiff_t(n * std::size_t(columns.channels())));
  }
  return all;
}

void expect_same_rows(const ReadRows& a, const ReadRows& b) {
  EXPECT_TRUE(a.directions == b.directions);
  EXPECT_TRUE(a.pdfs == b.pdfs);
  EXPECT_TRUE(a.weights == b.weights);
}

}  // namespace

TEST_F(SampleIo, FortranOrderReadsAsCOrderInAnyBlockSize) {
  const auto rows = five_column_rows(3000, 7);
  const SampleColumns c = SampleColumns::parse("x,y,z,pdf,weight");
  const std::string shape = "(" + std::to_string(rows.size()) + ", 5)";
  for (const bool f4 : {false, true}) {
    const std::string descr = f4 ? "<f4" : "<f8";
    const fs::path c_order = write_bytes("c.npy", npy_bytes(1, 0, dict(descr, shape), array_data(rows, false, f4)));
    const fs::path f_order = write_bytes("f.npy", npy_bytes(1, 0, dict(descr, shape, "True"), array_data(rows, true, f4)));
    const ReadRows expected = read_all(c_order, c, 1 << 16);
    ASSERT_EQ(expected.directions.size(), rows.size());
    for (const std::size_t block : {std::size_t(1), std::size_t(7), std::size_t(1) << 16}) {
      SCOPED_TRACE(descr + " block " + std::to_string(block));
      expect_same_rows(read_all(f_order, c, block), expected);
    }
    EXPECT_EQ(DirectionSampleReader(f_order, c).storage(), f4 ? "float32 .npy" : "float64 .npy");
  }
}

// Large enough that the reader gives back the pages of each column as it goes (16 MiB over 3 columns).
TEST_F(SampleIo, FortranOrderLargeFileReadsAsCOrder) {
  std::vector<std::vector<double>> rows;
  for (const Vec3<double>& w : random_unit_vectors(800000, 8)) rows.push_back({w.x(), w.y(), w.z()});
  const std::string shape = "(" + std::to_string(rows.size()) + ", 3)";
  const fs::path c_order = write_bytes("c.npy", npy_bytes(1, 0, dict("<f8", shape), array_data(rows, false, false)));
  const fs::path f_order = write_bytes("f.npy", npy_bytes(1, 0, dict("<f8", shape, "True"), array_data(rows, true, false)));
  expect_same_rows(read_all(f_order, SampleColumns{}, kSampleFileBlock), read_all(c_order, SampleColumns{}, kSampleFileBlock));
  EXPECT_TRUE(parse_direction_samples(slurp(f_order), "f.npy") == read_direction_samples(c_order));
}

TEST_F(SampleIo, FortranOrderErrorsNameTheRow) {
  auto rows = five_column_rows(4, 9);  // 8 rows: 4 random, 4 awkward
  rows[2][1] += 0.5;                   // row 2 is not unit length
  const SampleColumns c = SampleColumns::parse("x,y,z,pdf,weight");
  const fs::path bad = write_bytes("bad.npy", npy_bytes(1, 0, dict("<f8", "(8, 5)", "True"), array_data(rows, true, false)));
  EXPECT_THROW(
      {
        try {
          read_all(bad, c, 16);
        } catch (const SampleFileError& e) {
          EXPECT_NE(std::string(e.what()).find("row 2 (0-based)"), std::string::npos) << e.what();
          throw;
        }
      },
      SampleFileError);
  // The data ends in the last column: the rows it lacks are counted as in C order (88 of 96 bytes: 3 rows).
  expect_error(write_bytes("trunc.npy", npy_bytes(1, 0, dict("<f8", "(4, 3)", "True"), std::string(88, '\0'))),
               {"truncated", "row 3"});
}

// ---- extra columns (validate --columns) -------------------------------------------------------------------

TEST(SampleColumns, ParsesNamesAndRefusesBadSpecs) {
  const SampleColumns c = SampleColumns::parse("pdf,x,y,z,-,weight,weight");
  EXPECT_EQ(c.count, 7);
  EXPECT_EQ(c.direction, (std::array<int, 3>{1, 2, 3}));
  EXPECT_EQ(c.pdf, 0);
  EXPECT_EQ(c.weights, (std::vector<int>{5, 6}));
  EXPECT_EQ(c.describe(), "pdf x y z - weight weight");
  EXPECT_EQ(SampleColumns{}.describe(), "x y z");
  for (const char* bad : {"x,y", "x,x,y,z", "x,y,z,pdf,pdf", "x,y,z,w", "x,,y,z", ""}) {
    EXPECT_THROW(SampleColumns::parse(bad), std::invalid_argument) << bad;
  }
}

// A row of another count than --columns names: the message suggests a --columns that matches, with a '-'
// for each column more or without the trailing pdf, weights and '-' for each column fewer.
TEST_F(SampleIo, AColumnCountMismatchSuggestsMatchingColumns) {
  const auto message = [&](const std::string& name, const std::string& bytes, const char* spec) {
    try {
      DirectionSampleReader r(write_bytes(name, bytes), SampleColumns::parse(spec));
      std::vector<Vec3<double>> d(4);
      std::vector<double> pdfs(4), weights(16);
      r.read(d, pdfs, weights);
    } catch (const SampleFileError& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "no error for " << name;
    return std::string();
  };
  const std::string six = f8_data({0, 0, 1, 1, 1, 1}), five = f8_data({0, 0, 1, 1, 1});
  const std::vector<std::tuple<std::string, std::string, const char*, std::string>> cases = {
      {"six.npy", npy_bytes(1, 0, dict("<f8", "(1, 6)"), six), "x,y,z,pdf", "give --columns x,y,z,pdf,-,-"},
      {"one.npy", npy_bytes(1, 0, dict("<f8", "(1, 5)"), five), "z,x,y,weight,-,pdf,weight", "give --columns z,x,y,weight,-"},
      {"few.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 0, 1})), "x,pdf,y,z", "give --columns x,y,z"},
      {"two.npy", npy_bytes(1, 0, dict("<f8", "(1, 2)"), f8_data({0, 1})), "x,y,z", "names 3: a row needs x, y and z"},
      {"five.txt", "0 0 1 1 1\n", "x,y,z,pdf", "found 5 numbers, --columns x,y,z,pdf names 4: give --columns x,y,z,pdf,-"},
  };
  for (const auto& [name, bytes, spec, expected] : cases)
    EXPECT_NE(message(name, bytes, spec).find(expected), std::string::npos) << message(name, bytes, spec);
}

TEST_F(SampleIo, ExtraColumnsGoToPdfsAndWeights) {
  const SampleColumns c = SampleColumns::parse("x,y,z,pdf,weight");
  DirectionSampleReader text(write_bytes("five.txt", "0 0 1 0.5 0.9\n0.6 0 0.8 2.5 1.1\n"), c);
  std::vector<Vec3<double>> d(4);
  std::vector<double> pdfs(4), weights(4);
  ASSERT_EQ(text.read(d, pdfs, weights), 2u);
  EXPECT_EQ(d[1], Vec3<double>(0.6, 0, 0.8).normalized());
  EXPECT_EQ(pdfs[0], 0.5);
  EXPECT_EQ(pdfs[1], 2.5);
  EXPECT_EQ(weights[1], 1.1);
  DirectionSampleReader npy(write_bytes("five.npy", npy_bytes(1, 0, dict("<f4", "(1, 5)"), f4_data({0, 0, 1, 0.25f, 0.75f}))), c);
  ASSERT_EQ(npy.read(d, pdfs, weights), 1u);
  EXPECT_EQ(pdfs[0], 0.25);
  EXPECT_EQ(weights[0], 0.75);
  EXPECT_TRUE(npy.is_float32());
  // The shape and the column count must match the spec; the message says what was expected.
  try {
    DirectionSampleReader wrong(write_bytes("three.npy", npy_bytes(1, 0, dict("<f8", "(1, 3)"), f8_data({0, 0, 1}))), c);
    ADD_FAILURE() << "no error";
  } catch (const SampleFileError& e) {
    EXPECT_NE(std::string(e.what()).find("the file has 3 column(s), --columns x,y,z,pdf,weight names 5: give --columns x,y,z"),
              std::string::npos) << e.what();
  }
  try {
    DirectionSampleReader four(write_bytes("four.npy", npy_bytes(1, 0, dict("<f8", "(1, 4)"), f8_data({0, 0, 1, 1}))));
    ADD_FAILURE() << "no error";
  } catch (const SampleFileError& e) {
    EXPECT_NE(std::string(e.what()).find("the file has 4 column(s), --columns x,y,z (the default) names 3: give "
                                         "--columns x,y,z,- ('-' ignores a column)"), std::string::npos) << e.what();
  }
  try {  // numpy's (3, N): one sample per column
    DirectionSampleReader columns(write_bytes("t.npy", npy_bytes(1, 0, dict("<f8", "(3, 4)"), f8_data({0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1}))));
    ADD_FAILURE() << "no error";
  } catch (const SampleFileError& e) {
    EXPECT_NE(std::string(e.what()).find("one sample per column; the rows are samples, shape (N, 3): save the transpose"),
              std::string::npos) << e.what();
  }
  DirectionSampleReader short_text(write_bytes("short.txt", "0 0 1 0.5\n"), c);
  EXPECT_THROW(short_text.read(d, pdfs, weights), SampleFileError);
}

}  // namespace test_sample_io
