#!/usr/bin/python3
"""Self-test of scripts/function_lengths.py: the scanner on a file of awkward C++ (literals holding
braces, digit separators, raw strings, constructor brace initializers, operators, nested classes,
namespace-scope lambdas), the distribution, and the --max gate's exit status."""
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "scripts", "function_lengths.py")
sys.path.insert(0, os.path.dirname(SCRIPT))
import function_lengths  # noqa: E402

AWKWARD = r'''#include <string>
#define OPEN {
#define MACRO(x) \
  do { x; } while (0)
namespace outer { namespace inner {
// a comment with a { brace
/* a block comment } with
   a brace */
int digits() {
  const long n = 1'000'000;
  const char c = '{';
  return n + c;
}
const char* raw() {
  return R"x(a } raw { string)x";
}
std::string quoted() { return "} // not a comment"; }
}  // namespace inner

struct Point {
  double x{0}, y = 1;
  Point() = default;
  Point(double a, double b) : x{a}, y(b) {
    x += 1;
  }
  bool operator==(const Point& other) const {
    return x == other.x;
  }
  double operator()(double t) const { return t; }
  struct Nested {
    int get() const { return 1; }
  };
  enum class Kind { a, b };
};

template <typename T>
auto twice(T t) -> decltype(t + t) {
  return t + t;
}

const auto square = [](double v) {
  return v * v;
};
static const int kTable[] = {1, 2, 3};
Point::Nested make_nested() {
  auto lambda = [](int v) {
    return v;
  };
  struct Local { int f() { return 2; } };
  return Point::Nested{};
}
}  // namespace outer
extern "C" {
int c_entry(void) { return 0; }
}
Registration reg{"name", [](int& app) {
  app += 1;
}};
int values[] = {kTable[0], [] { return 1; }()};
'''


class ScannerTest(unittest.TestCase):
    def scan(self, text):
        with tempfile.NamedTemporaryFile("w", suffix=".cpp", delete=False) as f:
            f.write(text)
        try:
            return function_lengths.scan_file(f.name)
        finally:
            os.unlink(f.name)

    def test_awkward_file(self):
        found = {(fn["name"], fn["line"], fn["lines"]) for fn in self.scan(AWKWARD)}
        expected = {
            ("digits", 9, 5),
            ("raw", 14, 3),
            ("quoted", 17, 1),
            ("Point::Point", 23, 3),
            ("Point::operator==", 26, 3),
            ("Point::operator()", 29, 1),
            ("Point::Nested::get", 31, 1),
            ("twice", 36, 4),
            ("square", 41, 3),
            ("make_nested", 45, 7),
            ("c_entry", 54, 1),
            ("reg lambda", 56, 3),
            ("values lambda", 59, 1),
        }
        self.assertEqual(found, expected)

    def test_unbalanced_brace_is_an_error(self):
        with self.assertRaises(function_lengths.ScanError):
            self.scan("int f() {\n  return 1;\n")

    def test_distribution_buckets(self):
        functions = [{"lines": n} for n in (1, 20, 21, 40, 41, 80, 81, 150, 151)]
        self.assertEqual(function_lengths.distribution(functions),
                         {"<=20": 2, "21-40": 2, "41-80": 2, "81-150": 2, ">150": 1})

    def test_max_gate_exit_status(self):
        with tempfile.TemporaryDirectory() as root:
            os.mkdir(os.path.join(root, "src"))
            body = "".join(f"  x += {k};\n" for k in range(10))
            with open(os.path.join(root, "src", "a.cpp"), "w") as f:
                f.write("int f(int x) {\n" + body + "  return x;\n}\n")  # 13 lines
            def run(*extra):
                return subprocess.run([sys.executable, SCRIPT, "--root", root, *extra],
                                      capture_output=True, text=True).returncode
            self.assertEqual(run("--max", "13"), 0)
            self.assertEqual(run("--max", "12"), 1)
            self.assertEqual(run("--max", "0"), 2)


if __name__ == "__main__":
    unittest.main()
