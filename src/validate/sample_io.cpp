// microsim: NPY and text files of sampled directions (see src/validate/sample_io.h).
//
// The NPY format is tiny and specified at numpy.org (numpy.lib.format): the magic "\x93NUMPY", a major
// and minor version byte, a little-endian header length (uint16 for version 1.0, uint32 for 2.0 and
// 3.0), then an ASCII (1.0, 2.0) or UTF-8 (3.0) Python dict literal with exactly the keys 'descr',
// 'fortran_order' and 'shape', padded with spaces and ended by '\n'; the raw array data follows.
#include "validate/sample_io.h"

#include "core/strict_parse.h"
#include "core/atomic_file.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cerrno>

namespace microsim {
namespace {

constexpr std::string_view kNpyMagic = "\x93NUMPY";
// A zip archive (numpy's .npz, np.savez): several arrays, not one table of samples.
constexpr std::string_view kZipMagic = "PK\x03\x04";
constexpr const char* kNpzMessage = "a zip archive (numpy's .npz from np.savez), not one array: save the samples with "
                                    "np.save(PATH.npy, array) or as text";

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what) {
  throw SampleFileError(path.string() + ": " + what);
}

std::string format_double(double x) {
  std::array<char, 64> buf{};
  const auto r = std::to_chars(buf.data(), buf.data() + buf.size(), x);
  return std::string(buf.data(), r.ptr);
}

std::string format_vector(const Vec3<double>& w) {
  std::string s = "(";  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "lit" + string&&
  s += format_double(w.x()) + ", " + format_double(w.y()) + ", " + format_double(w.z()) + ")";
  return s;
}

// Tolerances are powers of ten: print them as "1e-4" (to_chars would give "1e-04").
std::string format_tolerance(double t) {
  const double e = std::round(std::log10(t));
  return t == std::pow(10.0, e) ? "1e" + std::to_string(static_cast<int>(e)) : format_double(t);
}

// A row that is the sampler's failure, not a malformed file: a non-finite value or the zero vector.
bool is_sampler_failure(const Vec3<double>& w) { return !w.allFinite() || w == Vec3<double>::Zero(); }

// Checks one row and returns it renormalised, or a NaN vector for a sampler failure (recorded in
// `invalid`). `where()` names the row ("line 12" or "row 5 (0-based)"); it is called only when needed.
template <class Where>
Vec3<double> checked_direction(const std::filesystem::path& path, const Where& where, const Vec3<double>& w,
                               double tolerance, const char* precision_name, InvalidRows& invalid) {
  if (is_sampler_failure(w)) {
    invalid.add(where());
    return Vec3<double>::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  const double len = w.norm();
  if (!(std::abs(len - 1.0) <= tolerance)) {
    fail(path, where() + ": vector " + format_vector(w) + " has length " + format_double(len) +
                   ", not unit length (| |w| - 1 | must be <= " + format_tolerance(tolerance) + " for " +
                   precision_name + ")");
  }
  return w / len;
}

// The extra values of a row (its pdf, then its weights), in the order SampleColumns lists them.
std::size_t extras_per_row(const SampleColumns& c) { return std::size_t(c.has_pdf()) + c.weights.size(); }

// The row's values -> its direction (checked) and extras appended to `extras`.
template <class Value, class Where>
Vec3<double> split_row(const std::filesystem::path& path, const Where& where, const Value& value, const SampleColumns& c,
                       double tolerance, const char* precision_name, InvalidRows& invalid, double* extras) {
  const Vec3<double> w(value(c.direction[0]), value(c.direction[1]), value(c.direction[2]));
  std::size_t k = 0;
  if (c.has_pdf()) extras[k++] = value(c.pdf);
  for (const int col : c.weights) extras[k++] = value(col);
  return checked_direction(path, where, w, tolerance, precision_name, invalid);
}

// ---- the column count -------------------------------------------------------------------------------------

// The names of `columns` as --columns spells them: "x,y,z,pdf".
std::string columns_spec(const SampleColumns& columns) {
  std::string s = columns.describe();
  std::replace(s.begin(), s.end(), ' ', ',');
  return s;
}

// A --columns for rows of `found` values from the names of `columns`: a '-' (ignored) for each value more, or
// for each value fewer one name other than x, y, z left out from the end; empty when none fits (x, y and z
// need three columns; a row of very many values gets no list of dashes).
std::string matching_columns(const SampleColumns& columns, std::uint64_t found) {
  constexpr std::uint64_t kMostSuggested = 32;
  if (found < 3 || found > kMostSuggested) return {};
  std::vector<std::string> names;
  std::istringstream words(columns.describe());
  for (std::string w; words >> w;) names.push_back(w);
  while (names.size() < found) names.emplace_back("-");
  for (std::size_t i = names.size(); names.size() > found && i-- > 0;)
    if (names[i] != "x" && names[i] != "y" && names[i] != "z") names.erase(names.begin() + std::ptrdiff_t(i));
  std::string spec;
  for (const std::string& n : names) spec += (spec.empty() ? "" : ",") + n;
  return spec;
}

// What to say after the count of `found` values in a row when `columns` names another count: the columns
// given, and a --columns that matches.
std::string column_count_advice(const SampleColumns& columns, std::uint64_t found) {
  const std::string given = columns_spec(columns);
  std::string s = "--columns " + given + (given == "x,y,z" ? " (the default)" : "") + " names " +
                  std::to_string(columns.count);
  const std::string match = matching_columns(columns, found);
  if (!match.empty())
    return s + ": give --columns " + match +
           (found > std::uint64_t(columns.count) ? " ('-' ignores a column), or name the extra columns (pdf, weight)" : "");
  return s + (found < 3 ? ": a row needs x, y and z" : "");
}

// ---- NPY -----------------------------------------------------------------------------------------------

struct NpyHeader {
  std::string descr;
  bool fortran_order = false;
  std::vector<std::uint64_t> shape;
};

// A recursive-descent reader for the one Python dict literal that NPY headers contain.
class NpyHeaderParser {
public:
  NpyHeaderParser(const std::filesystem::path& path, std::string_view text) : path_(path), s_(text) {}

  NpyHeader parse() {
    NpyHeader h;
    bool have_descr = false, have_order = false, have_shape = false;
    skip_space();
    expect('{');
    for (;;) {
      skip_space();
      if (peek() == '}') break;
      const std::string key = parse_string("a key");
      skip_space();
      expect(':');
      skip_space();
      if (key == "descr") {
        if (peek() != '\'' && peek() != '"')
          error("unsupported dtype: 'descr' is not a simple type string (structured arrays are not "
                "supported; expected float32 or float64: '<f4', '<f8', '>f4' or '>f8')");
        h.descr = parse_string("the 'descr' value");
        have_descr = true;
      } else if (key == "fortran_order") {
        h.fortran_order = parse_bool();
        have_order = true;
      } else if (key == "shape") {
        h.shape = parse_tuple();
        have_shape = true;
      } else {
        error("unexpected key " + reader::quote_excerpt(key) +
              " (an NPY header has exactly 'descr', 'fortran_order', 'shape')");
      }
      skip_space();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() != '}') error("expected ',' or '}' after the value of " + reader::quote_excerpt(key));
    }
    ++pos_;  // '}'
    skip_space();
    if (pos_ != s_.size()) error("unexpected text after the header dict");
    if (!have_descr || !have_order || !have_shape)
      error("the header dict lacks one of 'descr', 'fortran_order', 'shape'");
    return h;
  }

private:
  [[noreturn]] void error(const std::string& what) const { fail(path_, "NPY header: " + what); }

  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void skip_space() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r'))
      ++pos_;
  }
  void expect(char c) {
    if (peek() != c) error(std::string("expected '") + c + "' at offset " + std::to_string(pos_));
    ++pos_;
  }
  std::string parse_string(const char* what) {
    const char quote = peek();
    if (quote != '\'' && quote != '"') error(std::string("expected a quoted string as ") + what);
    ++pos_;
    const std::size_t end = s_.find(quote, pos_);
    if (end == std::string_view::npos) error("unterminated string");
    std::string out(s_.substr(pos_, end - pos_));
    pos_ = end + 1;
    return out;
  }
  bool parse_bool() {
    if (s_.substr(pos_, 4) == "True") {
      pos_ += 4;
      return true;
    }
    if (s_.substr(pos_, 5) == "False") {
      pos_ += 5;
      return false;
    }
    error("'fortran_order' must be True or False");
  }
  std::vector<std::uint64_t> parse_tuple() {
    std::vector<std::uint64_t> dims;
    expect('(');
    for (;;) {
      skip_space();
      if (peek() == ')') break;
      const char* first = s_.data() + pos_;
      std::uint64_t v = 0;
      const auto r = std::from_chars(first, s_.data() + s_.size(), v);
      if (r.ec != std::errc() || r.ptr == first) error("'shape' must be a tuple of non-negative integers");
      pos_ += static_cast<std::size_t>(r.ptr - first);
      if (peek() == 'L') ++pos_;  // Python 2 long suffix, written by old NumPy versions
      dims.push_back(v);
      skip_space();
      if (peek() == ',') {
        ++pos_;
        continue;
      }
      if (peek() != ')') error("'shape' must be a tuple of non-negative integers");
    }
    ++pos_;  // ')'
    return dims;
  }

  const std::filesystem::path& path_;
  std::string_view s_;
  std::size_t pos_ = 0;
};

std::uint64_t read_le(const unsigned char* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

// A value of `bytes` bytes stored most significant byte first (an NPY dtype '>f4' or '>f8').
std::uint64_t read_be(const unsigned char* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

// The float32 or float64 value at p, stored little- or big-endian whatever the machine's order (an NPY
// file's values, an array's columns).
double stored_value(const unsigned char* p, bool is_float32, bool big_endian) {
  if (is_float32) return std::bit_cast<float>(static_cast<std::uint32_t>(big_endian ? read_be(p, 4) : read_le(p, 4)));
  return std::bit_cast<double>(big_endian ? read_be(p, 8) : read_le(p, 8));
}

std::string shape_string(const std::vector<std::uint64_t>& shape) {
  std::string s = "(";
  const std::size_t shown = shape.size() <= 8 ? shape.size() : 4;  // a long tuple is cut: short messages
  for (std::size_t i = 0; i < shown; ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  if (shown < shape.size()) s += ", ... " + std::to_string(shape.size()) + " dimensions";
  if (shape.size() == 1) s += ",";
  return s + ")";
}

// Where the rows of a checked NPY file are: `bytes` is the whole file (a memory map).
struct NpyLayout {
  std::uint64_t rows = 0;
  std::size_t data_offset = 0;
  bool is_float32 = false;
  bool big_endian = false;     // dtype '>f4' or '>f8' (numpy's astype('>f8'), or a file saved on a big-endian machine)
  int columns = 3;
  bool fortran_order = false;  // column-major: each column's `rows` values are contiguous
  std::size_t item() const { return is_float32 ? 4 : 8; }
  // Byte offset in the file of the value of row r in column c (C order: row by row; Fortran order: column by
  // column, as numpy saves a transposed or column-indexed array).
  std::size_t offset(std::uint64_t r, int c) const {
    const std::uint64_t index = fortran_order ? std::uint64_t(c) * rows + r : r * std::uint64_t(columns) + std::uint64_t(c);
    return data_offset + std::size_t(index) * item();
  }
  // The runs of the data read front to back as the rows are read in order: the whole data in C order, each
  // column in Fortran order. After r rows, run s has been read up to offset(r, s).
  int runs() const { return fortran_order ? columns : 1; }
};

NpyLayout read_npy_layout(const std::filesystem::path& path, std::string_view bytes, const SampleColumns& columns) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t size = bytes.size();
  if (size < kNpyMagic.size() + 2) fail(path, "truncated NPY file (no complete version field)");
  const int major = data[6], minor = data[7];
  if (!((major == 1 || major == 2 || major == 3) && minor == 0))
    fail(path, "unsupported NPY version " + std::to_string(major) + "." + std::to_string(minor) +
                   " (supported: 1.0, 2.0, 3.0)");
  const std::size_t len_bytes = major == 1 ? 2 : 4;
  const std::size_t prefix = kNpyMagic.size() + 2 + len_bytes;
  if (size < prefix) fail(path, "truncated NPY file (no complete header length)");
  const std::uint64_t header_len = read_le(data + 8, static_cast<int>(len_bytes));
  if (header_len > size - prefix)
    fail(path, "truncated NPY header (declares " + std::to_string(header_len) + " bytes, file has " +
                   std::to_string(size - prefix) + ")");
  // Versions 1.0 and 2.0 have a latin-1 header, 3.0 UTF-8; every byte we accept is ASCII either way.
  const std::string_view header(bytes.data() + prefix, static_cast<std::size_t>(header_len));
  // The format ends the header with '\n' (after its padding); a file without it was not written by NumPy.
  if (header.empty()) fail(path, "NPY header is empty (header length 0)");
  if (header.back() != '\n')
    fail(path, "NPY header does not end with a newline '\\n' (its last byte is " +
                   reader::quote_excerpt(header.substr(header.size() - 1)) + ")");
  const NpyHeader h = NpyHeaderParser(path, header).parse();

  // Either byte order: numpy writes '<' on little-endian machines and for astype('<f8'), '>' for astype('>f8').
  if (h.descr != "<f4" && h.descr != "<f8" && h.descr != ">f4" && h.descr != ">f8")
    fail(path, "unsupported NPY dtype " + reader::quote_excerpt(h.descr) +
                   " (expected float32 or float64: '<f4', '<f8', '>f4' or '>f8')");
  const bool big_endian = h.descr[0] == '>';
  const bool is_float32 = h.descr[2] == '4';
  const std::size_t item = is_float32 ? 4 : 8;
  if (h.shape.size() != 2)
    fail(path, "unsupported NPY shape " + shape_string(h.shape) + " (expected (N, " + std::to_string(columns.count) +
                   "): " + columns.describe() + ")");
  if (h.shape[1] != std::uint64_t(columns.count) && h.shape[0] == std::uint64_t(columns.count))
    fail(path, "NPY shape " + shape_string(h.shape) + ": one sample per column; the rows are samples, shape (N, " +
                   std::to_string(columns.count) + "): save the transpose (numpy: np.save(path, a.T))");
  if (h.shape[1] != std::uint64_t(columns.count))
    fail(path, "NPY shape " + shape_string(h.shape) + ": the file has " + std::to_string(h.shape[1]) + " column(s), " +
                   column_count_advice(columns, h.shape[1]));
  const std::uint64_t rows = h.shape[0];
  if (rows == 0) fail(path, "empty: the NPY array has 0 rows (shape (0, 3))");

  const std::size_t row_bytes = std::size_t(columns.count) * item;
  const std::size_t available = size - prefix - static_cast<std::size_t>(header_len);
  const std::uint64_t complete_rows = available / row_bytes;
  if (complete_rows < rows)
    fail(path, "truncated NPY data: shape " + shape_string(h.shape) + " declares " + std::to_string(rows) +
                   " rows but the data ends in row " + std::to_string(complete_rows) + " (0-based; " +
                   std::to_string(available) + " data bytes for rows of " + std::to_string(row_bytes) + " bytes)");
  if (available != rows * row_bytes)
    fail(path, "NPY data has " + std::to_string(available - rows * row_bytes) +
                   " unexpected trailing bytes after the " + std::to_string(rows) + " declared rows");

  return NpyLayout{rows, prefix + static_cast<std::size_t>(header_len), is_float32, big_endian, columns.count,
                   h.fortran_order};
}

// Decodes and checks rows [first, first + out.size()) of a checked NPY file (`bytes` as above); the extra
// values of row i go to extras[i * extras_per_row(columns) ...].
void decode_npy_rows(const std::filesystem::path& path, std::string_view bytes, const NpyLayout& layout,
                     const SampleColumns& columns, std::uint64_t first, std::span<Vec3<double>> out, double* extras,
                     InvalidRows& invalid) {
  const bool is_float32 = layout.is_float32;
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const double tolerance = is_float32 ? kUnitLengthToleranceFloat32 : kUnitLengthToleranceFloat64;
  const char* precision_name = is_float32 ? "float32 data" : "float64 data";
  const std::size_t stride = extras_per_row(columns);
  for (std::uint64_t i = 0; i < out.size(); ++i) {
    const std::uint64_t r = first + i;
    const auto value = [&](int c) -> double {
      return stored_value(data + layout.offset(r, c), is_float32, layout.big_endian);
    };
    const auto where = [r] { return "row " + std::to_string(r) + " (0-based)"; };
    out[i] = split_row(path, where, value, columns, tolerance, precision_name, invalid, extras + i * stride);
  }
}

// ---- arrays in memory -------------------------------------------------------------------------------

// Value of row r of an array column (read byte by byte: a strided view need not be aligned).
double array_value(const SampleArrayColumn& column, std::uint64_t r) {
  const char* p = static_cast<const char*>(column.data) + std::ptrdiff_t(r) * column.stride;
  return stored_value(reinterpret_cast<const unsigned char*>(p), column.is_float32, column.big_endian);
}

bool array_directions_are_float32(const SampleArray& array, const SampleColumns& columns) {
  for (const int c : columns.direction)
    if (array.columns[std::size_t(c)].is_float32) return true;
  return false;
}

// Decodes and checks rows [first, first + out.size()) of an array, as decode_npy_rows does a file's.
void decode_array_rows(const SampleArray& array, const SampleColumns& columns, std::uint64_t first,
                       std::span<Vec3<double>> out, double* extras, InvalidRows& invalid) {
  const bool is_float32 = array_directions_are_float32(array, columns);
  const double tolerance = is_float32 ? kUnitLengthToleranceFloat32 : kUnitLengthToleranceFloat64;
  const char* precision_name = is_float32 ? "float32 data" : "float64 data";
  const std::filesystem::path name(array.name);
  const std::size_t stride = extras_per_row(columns);
  for (std::uint64_t i = 0; i < out.size(); ++i) {
    const std::uint64_t r = first + i;
    const auto value = [&](int c) { return array_value(array.columns[std::size_t(c)], r); };
    const auto where = [r] { return "row " + std::to_string(r) + " (0-based)"; };
    out[i] = split_row(name, where, value, columns, tolerance, precision_name, invalid, extras + i * stride);
  }
}

// ---- text ----------------------------------------------------------------------------------------------

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Half a unit in the last digit of a number as printed (token as read: sign, digits, point, exponent):
// "0.1234" 5e-5, "-1.5e-03" 5e-5, "12" 0.5; 0 for "nan" and "inf".
double printed_half_unit(std::string_view token) {
  std::size_t i = 0;
  if (i < token.size() && (token[i] == '+' || token[i] == '-')) ++i;
  if (i == token.size() || !(std::isdigit(static_cast<unsigned char>(token[i])) || token[i] == '.')) return 0;
  int decimals = 0;
  while (i < token.size() && std::isdigit(static_cast<unsigned char>(token[i]))) ++i;
  if (i < token.size() && token[i] == '.')
    for (++i; i < token.size() && std::isdigit(static_cast<unsigned char>(token[i])); ++i) ++decimals;
  int exponent = 0;
  if (i < token.size() && (token[i] == 'e' || token[i] == 'E')) {
    const std::size_t e = i + 1 < token.size() && token[i + 1] == '+' ? i + 2 : i + 1;
    std::from_chars(token.data() + e, token.data() + token.size(), exponent);
  }
  return 0.5 * std::pow(10.0, double(exponent) - double(decimals));
}

// The rows parsed from text, with their extra values (extras_per_row(columns) each) and printed rounding.
struct TextRows {
  std::vector<Vec3<double>> rows;
  std::vector<double> extras;
  std::vector<PrintedRounding> rounding;
  void clear() {
    rows.clear();
    extras.clear();
    rounding.clear();
  }
};

// Parses the lines of `text` (whole lines; the last may lack its '\n'), appending their rows to `out`;
// line_no counts the lines read so far (over all the chunks of a file).
void read_text_lines(const std::filesystem::path& path, std::string_view text, std::size_t& line_no,
                     const SampleColumns& columns, TextRows& out, InvalidRows& invalid) {
  std::vector<double> values, half_units;  // of a line, reused
  while (!text.empty()) {
    ++line_no;
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);

    const std::string where = "line " + std::to_string(line_no);
    const auto malformed = [&](const std::string& why) {
      fail(path, where + ": malformed line: " + why + " (expected three numbers separated by whitespace "
                         "or commas)");
    };
    values.clear();
    half_units.clear();
    std::size_t i = 0;
    const auto skip_blanks = [&] {
      while (i < line.size() && is_blank(line[i])) ++i;
    };
    skip_blanks();
    if (i == line.size()) continue;  // blank or comment-only line
    for (;;) {
      // One number.
      const std::size_t start = i;
      if (i < line.size() && line[i] == '+') ++i;  // from_chars rejects a leading '+'
      double v = 0.0;
      const auto r = std::from_chars(line.data() + i, line.data() + line.size(), v);
      const std::size_t end = static_cast<std::size_t>(r.ptr - line.data());
      std::size_t token_end = start;
      while (token_end < line.size() && !is_blank(line[token_end]) && line[token_end] != ',') ++token_end;
      const std::string_view token = line.substr(start, token_end - start);
      if (r.ec == std::errc::result_out_of_range)
        fail(path, where + ": value " + reader::quote_excerpt(token) + " is out of the range of a double");
      if (r.ec != std::errc() || end != token_end) {
        malformed(token.empty() ? std::string("empty field") : reader::quote_excerpt(token) + " is not a number");
      }
      values.push_back(v);
      half_units.push_back(printed_half_unit(token));
      i = end;
      // One separator: blanks, optionally one comma with blanks around it; or the end of the line.
      skip_blanks();
      if (i == line.size()) break;
      if (line[i] == ',') {
        ++i;
        skip_blanks();
        if (i == line.size()) malformed("trailing comma");
      }
    }
    if (values.size() != std::size_t(columns.count))
      fail(path, where + ": wrong column count: found " + std::to_string(values.size()) + " numbers, " +
                     column_count_advice(columns, values.size()));
    out.extras.resize(out.extras.size() + extras_per_row(columns));
    out.rows.push_back(split_row(path, [&where] { return where; }, [&values](int c) { return values[std::size_t(c)]; },
                                 columns, kUnitLengthToleranceText, "text data", invalid,
                                 out.extras.data() + out.extras.size() - extras_per_row(columns)));
    PrintedRounding r;
    for (const int c : columns.direction) r.direction = std::max(r.direction, half_units[std::size_t(c)]);
    if (columns.has_pdf()) r.pdf = half_units[std::size_t(columns.pdf)];
    for (const int c : columns.weights) r.weight = std::max(r.weight, half_units[std::size_t(c)]);
    out.rounding.push_back(r);
  }
}

// ---- writing -------------------------------------------------------------------------------------------

// Writes `bytes` to `path` atomically (microgeom/atomic_file.h).
void write_atomically(const std::filesystem::path& path, const std::string& bytes) {
  try {
    microsim::write_file_atomically(path, bytes);
  } catch (const microsim::FileWriteError& e) {
    throw SampleFileError(e.what());
  }
}

void append_le(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

}  // namespace

// ---- columns ---------------------------------------------------------------------------------------------

SampleColumns SampleColumns::parse(std::string_view spec) {
  SampleColumns c;
  c.count = 0;
  c.direction = {-1, -1, -1};
  const auto bad = [&](const std::string& why) {
    throw std::invalid_argument("'" + std::string(spec) + "': " + why + " (names: x, y, z, pdf, weight, - to skip)");
  };
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = spec.find(',', start);
    const std::string_view name = spec.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start);
    const int column = c.count++;
    if (name == "x" || name == "y" || name == "z") {
      int& d = c.direction[std::size_t(name[0] - 'x')];
      if (d >= 0) bad("column '" + std::string(name) + "' given twice");
      d = column;
    } else if (name == "pdf") {
      if (c.has_pdf()) bad("column 'pdf' given twice");
      c.pdf = column;
    } else if (name == "weight") {
      c.weights.push_back(column);
    } else if (name != "-") {
      bad(name.empty() ? "an empty item" : "unknown column '" + std::string(name.substr(0, 20)) + "'");
    }
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  for (const int d : c.direction)
    if (d < 0) bad("x, y and z are all needed");
  if (c.weights.size() > 16) bad("at most 16 weight columns");
  return c;
}

std::string SampleColumns::describe() const {
  std::vector<std::string> names(std::size_t(count), "-");
  for (int k = 0; k < 3; ++k) names[std::size_t(direction[std::size_t(k)])] = std::string(1, char('x' + k));
  if (has_pdf()) names[std::size_t(pdf)] = "pdf";
  for (const int w : weights) names[std::size_t(w)] = "weight";
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : " ") + n;
  return out;
}

// ---- the block reader ------------------------------------------------------------------------------

// Text is read in chunks of this many bytes; a line may be at most this long (its comment excepted).
constexpr std::size_t kTextChunk = std::size_t(1) << 20;

struct DirectionSampleReader::Impl {
  std::filesystem::path path;
  int fd = -1;
  std::uint64_t rows = 0;  // rows returned so far
  bool npy = false;
  std::optional<SampleArray> array;  // rows in memory instead of a file
  // NPY: the file mapped read-only (or, for a non-regular file, read into `owned`).
  void* map = nullptr;
  std::size_t map_size = 0;
  std::vector<std::size_t> released;  // per run of the data (NpyLayout::runs): where its pages given back end
  std::string owned;
  std::string_view bytes;
  NpyLayout layout;
  // Text: the unparsed tail of the chunks read, and the rows parsed from whole lines.
  std::string pending, chunk;
  TextRows parsed;
  SampleColumns columns;
  std::size_t parsed_pos = 0, line_no = 0;
  bool eof = false, bom_checked = false, in_comment = false;
  InvalidRows invalid;
  SampleFrame frame = SampleFrame::z_up;
  bool mirrored = false;  // z -> -z after the frame
  bool zero_weight_lost = false;

  ~Impl() {
    if (map) ::munmap(map, map_size);
    if (fd >= 0) ::close(fd);
  }

  std::size_t read_some(char* out, std::size_t n) {
    for (;;) {
      const ssize_t k = ::read(fd, out, n);
      if (k >= 0) return std::size_t(k);
      if (errno != EINTR) fail(path, "read error");
    }
  }
  void open_npy(bool regular, std::uint64_t size);
  std::size_t read_npy_rows(std::span<Vec3<double>> out, double* extras);
  void release_decoded_pages();
  std::size_t read_array_rows(std::span<Vec3<double>> out, double* extras);
  void parse_pending(std::size_t end);
  void shorten_long_line();
  bool refill_text();
};

void DirectionSampleReader::Impl::open_npy(bool regular, std::uint64_t size) {
  npy = true;
  if (regular) {
    map_size = std::size_t(size);
    map = ::mmap(nullptr, map_size, PROT_READ, MAP_PRIVATE, fd, 0);
    if (map == MAP_FAILED) {
      map = nullptr;
      fail(path, "cannot map the file for reading");
    }
    ::madvise(map, map_size, MADV_SEQUENTIAL);
    bytes = std::string_view(static_cast<const char*>(map), map_size);
  } else {  // a pipe or device: no map; read it whole
    char buf[1 << 16];
    while (const std::size_t k = read_some(buf, sizeof buf)) owned.append(buf, k);
    bytes = owned;
  }
  layout = read_npy_layout(path, bytes, columns);
}

std::size_t DirectionSampleReader::Impl::read_npy_rows(std::span<Vec3<double>> out, double* extras) {
  const std::size_t n = std::size_t(std::min<std::uint64_t>(out.size(), layout.rows - rows));
  decode_npy_rows(path, bytes, layout, columns, rows, out.first(n), extras, invalid);
  rows += n;
  if (map) release_decoded_pages();
  return n;
}

// Gives back the mapped pages decoded (those before where each run of the data has been read), 16 MiB at a
// time over all runs: resident memory stays bounded whatever the file's size or order. A page dropped that
// still holds the unread start of the next column is read again from the file when reached.
void DirectionSampleReader::Impl::release_decoded_pages() {
  const std::size_t page = std::size_t(::sysconf(_SC_PAGESIZE)), runs = std::size_t(layout.runs());
  if (released.empty())
    for (std::size_t s = 0; s < runs; ++s) released.push_back(layout.offset(0, int(s)) / page * page);
  for (std::size_t s = 0; s < runs; ++s) {
    const std::size_t done = layout.offset(rows, int(s)) / page * page;
    if (done > released[s] + (std::size_t(16) << 20) / runs || rows == layout.rows) {
      ::madvise(static_cast<char*>(map) + released[s], done - released[s], MADV_DONTNEED);
      released[s] = done;
    }
  }
}

std::size_t DirectionSampleReader::Impl::read_array_rows(std::span<Vec3<double>> out, double* extras) {
  const std::size_t n = std::size_t(std::min<std::uint64_t>(out.size(), array->rows - rows));
  decode_array_rows(*array, columns, rows, out.first(n), extras, invalid);
  rows += n;
  return n;
}

// Parses pending[0, end) (whole lines) into `parsed` and drops it from `pending`.
void DirectionSampleReader::Impl::parse_pending(std::size_t end) {
  std::string_view text(pending.data(), end);
  if (!bom_checked) {
    if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte order mark
    bom_checked = true;
  }
  read_text_lines(path, text, line_no, columns, parsed, invalid);
  pending.erase(0, end);
}

// `pending` holds more than a chunk without a line end: keep memory bounded. A comment is cut (the rest
// of it is skipped up to the line end), blanks are dropped; anything else is no line of three numbers.
void DirectionSampleReader::Impl::shorten_long_line() {
  if (const std::size_t hash = pending.find('#'); hash != std::string::npos) {
    pending.resize(hash + 1);
    in_comment = true;
    return;
  }
  if (pending.find_first_not_of(" \t\r\v\f") == std::string::npos) {
    pending.clear();
    return;
  }
  std::size_t n = line_no;
  TextRows ignored;
  InvalidRows ignored_invalid;
  read_text_lines(path, pending, n, columns, ignored, ignored_invalid);  // names the malformed token, as for a shorter line
  fail(path, "line " + std::to_string(line_no + 1) + ": longer than " + std::to_string(kTextChunk) +
                 " bytes without a line end (expected three numbers)");
}

// Reads chunks until some rows are parsed; false at the end of the file.
bool DirectionSampleReader::Impl::refill_text() {
  parsed.clear();
  parsed_pos = 0;
  chunk.resize(kTextChunk);
  while (parsed.rows.empty()) {
    if (eof) return false;
    const std::size_t k = read_some(chunk.data(), chunk.size());
    if (k == 0) {
      eof = true;
      parse_pending(pending.size());  // the last line, without its '\n'
      continue;
    }
    std::string_view data(chunk.data(), k);
    if (in_comment) {
      const std::size_t nl = data.find('\n');
      if (nl == std::string_view::npos) continue;
      data.remove_prefix(nl);
      in_comment = false;
    }
    pending.append(data);
    const std::size_t last = pending.rfind('\n');
    if (last != std::string::npos) parse_pending(last + 1);
    else if (pending.size() > kTextChunk) shorten_long_line();
  }
  return true;
}

DirectionSampleReader::DirectionSampleReader(const std::filesystem::path& path, SampleColumns columns)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = path;
  m.columns = std::move(columns);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail(path, "is a directory, not a sample file");
  m.fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (m.fd < 0) fail(path, "cannot open for reading");
  struct stat st {};
  if (::fstat(m.fd, &st) != 0) fail(path, "read error");
  const bool regular = S_ISREG(st.st_mode);
  // The first bytes tell NPY from text (pread: a regular file is then mapped from its start).
  char head[6] = {};
  std::size_t got = 0;
  if (regular) {
    const ssize_t k = ::pread(m.fd, head, sizeof head, 0);
    if (k < 0) fail(path, "read error");
    got = std::size_t(k);
  } else {
    got = m.read_some(head, sizeof head);
    m.pending.assign(head, got);
  }
  if (got == 0) fail(path, "empty file: no samples");
  if (std::string_view(head, got) == kNpyMagic) {
    if (!regular) m.owned.assign(head, got);
    m.open_npy(regular, std::uint64_t(st.st_size));
  } else if (path.extension() == ".npy") {
    fail(path, "not an NPY file (the magic string \\x93NUMPY is missing) although the name ends in .npy");
  } else if (std::string_view(head, got).starts_with(kZipMagic)) {
    fail(path, kNpzMessage);
  }
}

DirectionSampleReader::DirectionSampleReader(SampleArray array, SampleColumns columns) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (array.columns.size() != std::size_t(columns.count))
    throw std::invalid_argument("DirectionSampleReader: the array has " + std::to_string(array.columns.size()) +
                                " column(s), the columns spec " + std::to_string(columns.count));
  m.path = array.name;
  if (array.rows == 0) fail(m.path, "empty: the array has 0 rows");
  m.columns = std::move(columns);
  m.array = std::move(array);
}

DirectionSampleReader DirectionSampleReader::reopened() const {
  DirectionSampleReader r = impl_->array ? DirectionSampleReader(*impl_->array, impl_->columns)
                                         : DirectionSampleReader(impl_->path, impl_->columns);
  r.set_frame(impl_->frame);
  r.set_mirrored(impl_->mirrored);
  r.set_zero_weight_rows_lost(impl_->zero_weight_lost);
  return r;
}

DirectionSampleReader::~DirectionSampleReader() = default;
DirectionSampleReader::DirectionSampleReader(DirectionSampleReader&&) noexcept = default;
DirectionSampleReader& DirectionSampleReader::operator=(DirectionSampleReader&&) noexcept = default;

const std::filesystem::path& DirectionSampleReader::path() const { return impl_->path; }
std::uint64_t DirectionSampleReader::rows_read() const { return impl_->rows; }
const InvalidRows& DirectionSampleReader::invalid_rows() const { return impl_->invalid; }
std::string DirectionSampleReader::storage() const {
  if (impl_->array) return is_float32() ? "float32 array" : "float64 array";
  if (!impl_->npy) return "text";
  return impl_->layout.is_float32 ? "float32 .npy" : "float64 .npy";
}

std::size_t DirectionSampleReader::read(std::span<Vec3<double>> out, std::span<double> pdfs, std::span<double> weights,
                                       std::span<PrintedRounding> rounding) {
  const std::size_t n = read_as_stored(out, pdfs, weights, rounding);
  if (impl_->frame != SampleFrame::z_up)
    for (std::size_t i = 0; i < n; ++i) out[i] = to_z_up(impl_->frame, out[i]);
  if (impl_->mirrored)
    for (std::size_t i = 0; i < n; ++i) out[i].z() = -out[i].z();
  return n;
}

void DirectionSampleReader::set_frame(SampleFrame frame) { impl_->frame = frame; }
void DirectionSampleReader::set_mirrored(bool mirrored) { impl_->mirrored = mirrored; }
bool DirectionSampleReader::mirrored() const { return impl_->mirrored; }
void DirectionSampleReader::set_zero_weight_rows_lost(bool lost) {
  if (lost && impl_->columns.channels() == 0)
    throw std::invalid_argument("rows of weight 0 as lost samples: the dump has no weight column (--columns x,y,z,pdf,weight)");
  impl_->zero_weight_lost = lost;
}
bool DirectionSampleReader::zero_weight_rows_lost() const { return impl_->zero_weight_lost; }
SampleFrame DirectionSampleReader::frame() const { return impl_->frame; }
const SampleColumns& DirectionSampleReader::columns() const { return impl_->columns; }
bool DirectionSampleReader::is_float32() const {
  if (impl_->array) return array_directions_are_float32(*impl_->array, impl_->columns);
  return impl_->npy && impl_->layout.is_float32;
}

std::string to_string(SampleFrame frame) {
  switch (frame) {
    case SampleFrame::y_up: return "y-up";
    case SampleFrame::z_down: return "z-down";
    case SampleFrame::negated: return "negated";
    default: return "z-up";
  }
}

// The rows as stored; their extras (pdf, weights) scattered into pdfs and weights, their printed rounding
// into `rounding`.
std::size_t DirectionSampleReader::read_as_stored(std::span<Vec3<double>> out, std::span<double> pdfs,
                                                  std::span<double> weights, std::span<PrintedRounding> rounding) {
  Impl& m = *impl_;
  const std::size_t stride = extras_per_row(m.columns), channels = m.columns.weights.size();
  if (m.columns.has_pdf() && pdfs.size() < out.size()) throw std::invalid_argument("DirectionSampleReader: pdfs too short");
  if (weights.size() < out.size() * channels) throw std::invalid_argument("DirectionSampleReader: weights too short");
  if (!rounding.empty() && rounding.size() < out.size())
    throw std::invalid_argument("DirectionSampleReader: rounding too short");
  std::vector<double> extras;
  std::size_t n = 0;
  if (m.npy || m.array) {
    extras.resize(out.size() * stride);
    n = m.array ? m.read_array_rows(out, extras.data()) : m.read_npy_rows(out, extras.data());
    std::fill_n(rounding.begin(), rounding.empty() ? 0 : n, PrintedRounding{});
  } else {
    while (n < out.size()) {
      if (m.parsed_pos == m.parsed.rows.size() && !m.refill_text()) break;
      const std::size_t k = std::min(out.size() - n, m.parsed.rows.size() - m.parsed_pos);
      const auto from = std::ptrdiff_t(m.parsed_pos);
      std::copy_n(m.parsed.rows.begin() + from, k, out.begin() + std::ptrdiff_t(n));
      if (!rounding.empty()) std::copy_n(m.parsed.rounding.begin() + from, k, rounding.begin() + std::ptrdiff_t(n));
      extras.insert(extras.end(), m.parsed.extras.begin() + from * std::ptrdiff_t(stride),
                    m.parsed.extras.begin() + (from + std::ptrdiff_t(k)) * std::ptrdiff_t(stride));
      m.parsed_pos += k;
      n += k;
    }
    m.rows += n;
    if (n == 0 && m.rows == 0) fail(m.path, "empty: no samples (only blank or comment lines)");
  }
  for (std::size_t i = 0; i < n && stride > 0; ++i) {
    std::size_t k = i * stride;
    if (m.columns.has_pdf()) pdfs[i] = extras[k++];
    for (std::size_t c = 0; c < channels; ++c) weights[i * channels + c] = extras[k++];
  }
  return n;
}

std::vector<Vec3<double>> parse_direction_samples(std::string_view bytes, const std::filesystem::path& name) {
  if (bytes.empty()) fail(name, "empty file: no samples");
  if (bytes.substr(0, kNpyMagic.size()) == kNpyMagic) {
    const SampleColumns columns;
    const NpyLayout layout = read_npy_layout(name, bytes, columns);  // rows checked against the bytes present
    std::vector<Vec3<double>> out(static_cast<std::size_t>(layout.rows));
    InvalidRows invalid;
    decode_npy_rows(name, bytes, layout, columns, 0, out, nullptr, invalid);
    return out;
  }
  if (name.extension() == ".npy")
    fail(name, "not an NPY file (the magic string \\x93NUMPY is missing) although the name ends in .npy");
  if (bytes.starts_with(kZipMagic)) fail(name, kNpzMessage);
  if (bytes.substr(0, 3) == "\xEF\xBB\xBF") bytes.remove_prefix(3);  // UTF-8 byte order mark
  TextRows out;
  std::size_t line_no = 0;
  InvalidRows invalid;
  read_text_lines(name, bytes, line_no, SampleColumns{}, out, invalid);
  if (out.rows.empty()) fail(name, "empty: no samples (only blank or comment lines)");
  return std::move(out.rows);
}

std::vector<Vec3<double>> read_direction_samples(const std::filesystem::path& path) {
  DirectionSampleReader reader(path);
  std::vector<Vec3<double>> out, block(kSampleFileBlock);
  while (const std::size_t n = reader.read(block)) out.insert(out.end(), block.begin(), block.begin() + std::ptrdiff_t(n));
  return out;
}

void write_npy(const std::filesystem::path& path, std::span<const Vec3<double>> samples, bool as_float32) {
  std::vector<double> values;
  values.reserve(samples.size() * 3);
  for (const Vec3<double>& w : samples) values.insert(values.end(), {w.x(), w.y(), w.z()});
  write_npy_table(path, values, 3, as_float32);
}

void write_npy_table(const std::filesystem::path& path, std::span<const double> values, std::size_t columns, bool as_float32) {
  std::string header = "{'descr': '";
  header += as_float32 ? "<f4" : "<f8";
  header += "', 'fortran_order': False, 'shape': (" + std::to_string(values.size() / columns) + ", " +
            std::to_string(columns) + "), }";
  // Pad with spaces so that magic + version + length + header (ending in '\n') is a multiple of 64.
  const std::size_t prefix = kNpyMagic.size() + 2 + 2;
  const std::size_t total = (prefix + header.size() + 1 + 63) / 64 * 64;
  header.append(total - prefix - header.size() - 1, ' ');
  header.push_back('\n');

  std::string out(kNpyMagic);
  out.push_back('\x01');
  out.push_back('\x00');
  append_le(out, header.size(), 2);
  out += header;
  out.reserve(out.size() + values.size() * (as_float32 ? 4 : 8));
  for (const double v : values) {
    if (as_float32)
      append_le(out, std::bit_cast<std::uint32_t>(static_cast<float>(v)), 4);
    else
      append_le(out, std::bit_cast<std::uint64_t>(v), 8);
  }
  write_atomically(path, out);
}

void write_text_samples(const std::filesystem::path& path, std::span<const Vec3<double>> samples) {
  std::string out = "# microsim direction samples, local z-up frame: x y z (" + std::to_string(samples.size()) +
                    " rows)\n";
  for (const Vec3<double>& w : samples)
    out += format_double(w.x()) + " " + format_double(w.y()) + " " + format_double(w.z()) + "\n";
  write_atomically(path, out);
}

}  // namespace microsim
