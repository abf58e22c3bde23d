// microsim: reading and writing files of sampled directions, for `microsim validate --from FILE` (samples
// produced by a GLSL/HLSL/CUDA sampler elsewhere) and for dumping microsim's own samples.
//
// Formats (docs/reference/file-formats.md, "Sample files"):
// - NPY (NumPy format versions 1.0, 2.0 and 3.0; https://numpy.org/doc/stable/reference/generated/
//   numpy.lib.format.html): dtype '<f4', '<f8', '>f4' or '>f8' (float32/float64 in either byte order), shape (N, 3), in C order
//   (row by row) or Fortran order (fortran_order True: column by column, as np.save writes a transposed or
//   column-indexed array). Recognised by its magic string "\x93NUMPY", whatever the file name.
// - Text: three numbers per line separated by whitespace and/or single commas; '#' starts a comment that
//   runs to the end of the line; blank lines are ignored; CRLF line ends and a UTF-8 byte order mark
//   are accepted.
//
// Each row is a unit direction in the local z-up frame. A row whose length differs from 1 by more than
// the tolerance of its storage precision (below) is rejected: such a file almost certainly holds
// something else (unnormalised half vectors, a pdf column, the wrong array). Accepted rows are
// renormalised in double, so callers always receive unit vectors.
//
// A row with a non-finite value (nan, inf: text spells them as C's printf does, "nan", "-nan", "inf") or
// the zero vector is not a malformed file but the sampler's failure: it is passed on as a NaN vector
// (which the validator counts outside the domain: a rejection, exit 1) and recorded in InvalidRows.
//
// Every other problem throws SampleFileError with a message that names the file and the 1-based line
// (text) or the 0-based row index (NPY) of the problem.
#pragma once

#include "core/math.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

struct SampleFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The rows of a sample file that hold the sampler's failures (non-finite values or the zero vector):
// how many, and where the first kListed are ("row 5 (0-based)" for NPY, "line 12" for text).
struct InvalidRows {
  static constexpr std::size_t kListed = 5;
  std::uint64_t count = 0;
  std::vector<std::string> first;
  void add(std::string where) {
    ++count;
    if (first.size() < kListed) first.push_back(std::move(where));
  }
};

// Accepted | |w| - 1 | per storage precision. float64 NPY: 1e-6 admits float32 data widened to float64
// (float32 rounding of a normalised vector moves its length by at most ~2e-7, a few-ULP GPU rsqrt by
// a few 1e-7 more). float32 NPY: 1e-5 (= 84 ULP of 1.0f) also admits GPU approximate reciprocal square
// roots. Text: 1e-4 admits numbers printed with 4 decimals (rounding 5e-5 per component moves the
// length by at most ~8.7e-5). All are orders of magnitude below any genuine mistake.
inline constexpr double kUnitLengthToleranceFloat64 = 1e-6;
inline constexpr double kUnitLengthToleranceFloat32 = 1e-5;
inline constexpr double kUnitLengthToleranceText = 1e-4;

// The frame a file's rows are in, and the common frame mistakes of renderers' dumps, each as the map that
// brings its rows to microsim's z-up frame (the view's frame: --theta/--phi).
enum class SampleFrame {
  z_up,     // as stored
  y_up,     // normal along +y: rotated +90 deg about x, (x, y, z) -> (x, -z, y)
  z_down,   // the normal (or the view) pointing into the surface: (x, y, z) -> (x, y, -z)
  negated,  // directions flipped: w -> -w
};
inline Vec3<double> to_z_up(SampleFrame frame, const Vec3<double>& w) {
  switch (frame) {
    case SampleFrame::y_up: return {w.x(), -w.z(), w.y()};
    case SampleFrame::z_down: return {w.x(), w.y(), -w.z()};
    case SampleFrame::negated: return -w;
    default: return w;
  }
}
// "z-up", "y-up", "z-down", "negated".
std::string to_string(SampleFrame frame);

// Which columns of a row hold what: the direction (x, y, z), and optionally the pdf its sampler returned
// (per unit solid angle of the direction) and its weights (f cos / pdf, one column per channel), as a
// renderer's sample() returns them. Spelled as `validate --columns`: "x,y,z" (the default),
// "x,y,z,pdf", "x,y,z,pdf,weight", "x,y,z,weight,weight,weight", any order, "-" for a column to skip.
struct SampleColumns {
  int count = 3;                       // columns per row
  std::array<int, 3> direction{0, 1, 2};
  int pdf = -1;                        // -1: no pdf column
  std::vector<int> weights;            // the weight columns, a channel each
  bool has_pdf() const { return pdf >= 0; }
  int channels() const { return int(weights.size()); }
  // Throws std::invalid_argument naming the bad item (a missing or repeated x/y/z, a second pdf, an
  // unknown name, more than Material::kMaxChannels weights).
  static SampleColumns parse(std::string_view spec);
  std::string describe() const;  // "x y z", "x y z pdf weight"
};

// What the digits of a text row keep: half a unit in the last printed digit ("0.1234" 5e-5, "1.5e-03"
// 5e-5, "12" 0.5), the coarsest of its direction's three numbers, that of its pdf and of its weights. A
// renderer's dump printed with printf's %g or %.4f is that far from the values the renderer held; binary
// storage (NPY, arrays) has no printed digits: all are 0 and its precision (float32, float64) says it.
struct PrintedRounding {
  double direction = 0;  // absolute, per component
  double pdf = 0;        // absolute
  double weight = 0;     // absolute, the coarsest of the weight columns'
};

// Samples already in memory (a NumPy array handed over by the Python module, src/python): each column a
// strided view of float32 or float64 values, read in place (no copy). `stride` is in bytes between rows
// (any sign, any alignment). The rows get the checks of an NPY file's rows with the tolerance of the
// direction columns' precision (kUnitLengthToleranceFloat32 if any of x, y, z is float32), and the same
// messages, `name` standing for the path ("samples: row 5 (0-based): vector ... not unit length ...").
struct SampleArrayColumn {
  const void* data = nullptr;  // the value of row 0
  std::ptrdiff_t stride = 0;   // bytes from one row's value to the next
  bool is_float32 = false;     // float32, else float64
  bool big_endian = false;     // stored most significant byte first (numpy's '>f8'), else little-endian
};
struct SampleArray {
  std::string name = "samples";             // stands for a file's path in messages
  std::uint64_t rows = 0;
  std::vector<SampleArrayColumn> columns;   // indexed by SampleColumns (its count must match)
};

// Reads a sample file (NPY or text, as above) in blocks of rows, in memory bounded whatever its size: an
// NPY file through a read-only memory map whose pages are given back once decoded (in Fortran order each
// column is read front to back, from its own place in the map), text in chunks of
// 1 MiB, whole lines at a time (a line may be at most 1 MiB long, a comment excepted). The same checks
// and messages as read_direction_samples, which reads through it; a bad row throws when it is reached.
class DirectionSampleReader {
public:
  // Opens; checks an NPY header against the columns (shape (N, columns.count)).
  explicit DirectionSampleReader(const std::filesystem::path& path, SampleColumns columns = {});
  // Reads an array in memory (above) instead of a file; the array must outlive the reader. Throws
  // SampleFileError for 0 rows, and std::invalid_argument when its columns do not match `columns`.
  explicit DirectionSampleReader(SampleArray array, SampleColumns columns = {});
  ~DirectionSampleReader();
  DirectionSampleReader(DirectionSampleReader&&) noexcept;
  DirectionSampleReader& operator=(DirectionSampleReader&&) noexcept;

  // A new reader of the same file or array from its first row, with the same columns and frame (a second
  // pass over the samples, as the weight test makes).
  DirectionSampleReader reopened() const;

  // Fills `out` with the next rows, up to out.size(); returns how many (fewer only at the end, 0 after
  // it). Throws SampleFileError on a bad row, and at the end of a file that held no sample at all. With a
  // pdf column its values go to `pdfs` (at least out.size() of them), with weight columns to `weights`
  // (channels() per row, row-major); spans that are not needed may be empty. `rounding`, when not empty
  // (at least out.size()), receives each row's PrintedRounding.
  std::size_t read(std::span<Vec3<double>> out, std::span<double> pdfs = {}, std::span<double> weights = {},
                   std::span<PrintedRounding> rounding = {});
  const SampleColumns& columns() const;
  bool is_float32() const;  // an NPY file of float32 values, or an array whose directions are float32
  std::uint64_t rows_read() const;
  const std::filesystem::path& path() const;
  // The frame the rows are in (default z-up): read() returns them mapped to z-up (to_z_up).
  void set_frame(SampleFrame frame);
  SampleFrame frame() const;
  // Mirror every row in z after its frame (z -> -z): light from inside a dielectric validated as its mirror
  // image seen from outside (dump_validation.h, seen_from_outside).
  void set_mirrored(bool mirrored);
  bool mirrored() const;
  // Rows whose weights are all 0 are samples the sampler lost, kept in the dump: Mitsuba 3's sample() returns
  // a reflection below the horizon or a refraction on the wrong side with its direction, its pdf and weight
  // 0. Readers of blocks (validate.h, for_each_block) count them as failed samples. Needs weight columns.
  void set_zero_weight_rows_lost(bool lost);
  bool zero_weight_rows_lost() const;
  // How the rows are stored: "float32 .npy", "float64 .npy", "text", "float32 array" or "float64 array".
  std::string storage() const;
  // The rows read so far that hold the sampler's failures (see above).
  const InvalidRows& invalid_rows() const;

private:
  std::size_t read_as_stored(std::span<Vec3<double>> out, std::span<double> pdfs, std::span<double> weights,
                             std::span<PrintedRounding> rounding);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Rows per read of read_direction_samples (and a good block size for DirectionSampleReader::read).
inline constexpr std::size_t kSampleFileBlock = std::size_t(1) << 16;

// Reads sampled directions from an NPY or text file (see above; the sampler's failures are NaN vectors).
// Throws SampleFileError on a file that cannot be opened, a malformed line, a wrong column count, a
// nonzero vector far from unit length, an unsupported NPY version/dtype/shape, truncated or trailing data, or no samples at all.
std::vector<Vec3<double>> read_direction_samples(const std::filesystem::path& path);
// The same for the bytes of a file in memory (the fuzz target's entry point); `name` stands for the path
// in messages, and its extension .npy demands the NPY magic as for a file.
std::vector<Vec3<double>> parse_direction_samples(std::string_view bytes, const std::filesystem::path& name);

// Writes an NPY version 1.0 file with dtype '<f4' (as_float32) or '<f8' and shape (N, 3), C order.
// Written to a temporary file in the same directory and renamed, so nothing is ever half-written.
// Throws SampleFileError on an I/O error.
void write_npy(const std::filesystem::path& path, std::span<const Vec3<double>> samples, bool as_float32);
// A table of values.size() / columns rows, row-major, as an NPY (rows, columns) array; as write_npy.
void write_npy_table(const std::filesystem::path& path, std::span<const double> values, std::size_t columns, bool as_float32);

// Writes a text file: a '#' comment header, then one "x y z" line per sample with the shortest decimal
// representation that reads back to the same double (exact round trip). Same temp-file-and-rename
// discipline and errors as write_npy.
void write_text_samples(const std::filesystem::path& path, std::span<const Vec3<double>> samples);

}  // namespace microsim
