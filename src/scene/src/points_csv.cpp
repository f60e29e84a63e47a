#include "magvine/scene/points_csv.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "magvine/core/error.hpp"
#include "magvine/core/text.hpp"

namespace magvine::scene {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return out;
}

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return std::tolower(c); });
  return out;
}

}  // namespace

std::vector<Vec3> parse_points_csv(std::string_view text, const std::string& file_label) {
  std::vector<Vec3> points;
  bool have_header = false;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t nl = text.find('\n', pos);
    std::string_view line = text.substr(pos, nl == std::string_view::npos ? std::string_view::npos : nl - pos);
    pos = nl == std::string_view::npos ? text.size() + 1 : nl + 1;
    ++line_no;
    line = trim(line);
    if (line.empty() || line.front() == '#') continue;
    const auto cols = split(line);
    if (!have_header) {
      if (cols.size() != 3 || lower(cols[0]) != "x" || lower(cols[1]) != "y" || lower(cols[2]) != "z") {
        throw InputError(file_label, line_no, "header",
                         "expected the header line 'x,y,z' (metres), got '" + std::string(line) + "'");
      }
      have_header = true;
      continue;
    }
    if (cols.size() != 3) {
      throw InputError(file_label, line_no, "", "expected 3 columns x,y,z, got " + std::to_string(cols.size()));
    }
    Vec3 p;
    for (int i = 0; i < 3; ++i) {
      const std::string_view c = cols[static_cast<std::size_t>(i)];
      const char* name = i == 0 ? "x" : (i == 1 ? "y" : "z");
      double v = 0.0;
      const auto res = std::from_chars(c.data(), c.data() + c.size(), v);
      if (c.empty() || res.ec != std::errc() || res.ptr != c.data() + c.size()) {
        throw InputError(file_label, line_no, std::string("column ") + name,
                         "'" + std::string(c) + "' is not a number");
      }
      if (!std::isfinite(v)) {
        throw InputError(file_label, line_no, std::string("column ") + name,
                         "must be finite (got " + std::string(c) + ")");
      }
      p[i] = v;
    }
    points.push_back(p);
  }
  if (!have_header) throw InputError(file_label, 0, "", "empty file: expected a header 'x,y,z' and at least one point");
  if (points.empty()) throw InputError(file_label, 0, "", "no points after the header");
  return points;
}

std::vector<Vec3> read_points_csv(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file.string(), 0, "", "cannot open points file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_points_csv(ss.str(), file.string());
}

std::string field_csv_header() {
  return "x,y,z,Bx,By,Bz,G11,G12,G13,G21,G22,G23,G31,G32,G33";
}

void write_field_csv(std::ostream& out, std::span<const Vec3> points, std::span<const magnetics::FieldSample> samples) {
  std::string row;
  out << field_csv_header() << '\n';
  for (std::size_t k = 0; k < points.size(); ++k) {
    row.clear();
    const auto& s = samples[k];
    const double values[15] = {points[k].x(), points[k].y(), points[k].z(), s.b.x(),   s.b.y(),
                               s.b.z(),       s.g(0, 0),     s.g(0, 1),     s.g(0, 2), s.g(1, 0),
                               s.g(1, 1),     s.g(1, 2),     s.g(2, 0),     s.g(2, 1), s.g(2, 2)};
    append_csv_row(row, values);
    out << row;
  }
}

}  // namespace magvine::scene
