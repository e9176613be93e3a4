#include "zerog/formats/design_csv.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "zerog/formats/log.hpp"

namespace zerog::formats {
namespace {

constexpr const char* kJointNames[6] = {"q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad"};

std::string format_double(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.12g", x);
  return buf;
}

}  // namespace

bool read_design_line(std::istream& in, int& line_no, std::vector<std::string>& cells,
                      std::vector<int>& columns) {
  std::string line;
  while (true) {
    if (!std::getline(in, line)) return false;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] != '#') break;
  }
  cells.clear();
  columns.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    columns.push_back(static_cast<int>(start) + 1);
    cells.push_back(line.substr(start, comma == std::string::npos ? comma : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return true;
}

std::string design_csv_text(const std::string& comment,
                            const std::vector<DesignPoint>& points_rad) {
  std::ostringstream out;
  out << kDesignMagic << "\n";
  if (!comment.empty()) out << "# " << comment << "\n";
  for (int j = 0; j < 6; ++j) out << (j ? "," : "") << kJointNames[j];
  out << "\n";
  for (const auto& q : points_rad) {
    for (int j = 0; j < 6; ++j) out << (j ? "," : "") << format_double(q[j]);
    out << "\n";
  }
  return out.str();
}

std::vector<DesignPoint> read_design(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, 0, "cannot open design file");
  std::string line;
  int line_no = 0;
  if (!std::getline(in, line) || (++line_no, line != kDesignMagic))
    throw InputError(path, 1, 1, "first line must be '" + std::string(kDesignMagic) + "'");
  bool header_seen = false;
  std::vector<DesignPoint> points;
  std::vector<std::string> cells;
  std::vector<int> columns;
  while (read_design_line(in, line_no, cells, columns)) {
    if (cells.size() != 6)
      throw InputError(path, line_no, 1,
                       "expected 6 columns, found " + std::to_string(cells.size()));
    if (!header_seen) {
      for (int j = 0; j < 6; ++j)
        if (cells[j] != kJointNames[j])
          throw InputError(path, line_no, columns[j],
                           "header column " + std::to_string(j + 1) + " must be '" +
                               kJointNames[j] + "', found '" + cells[j] + "'");
      header_seen = true;
      continue;
    }
    DesignPoint q{};
    for (int j = 0; j < 6; ++j) {
      std::istringstream cell(cells[j]);
      cell.imbue(std::locale::classic());
      double x = 0.0;
      if (!(cell >> x) || !(cell >> std::ws).eof() || !std::isfinite(x))
        throw InputError(path, line_no, columns[j], "not a finite number: '" + cells[j] + "'");
      q[j] = x;
    }
    points.push_back(q);
  }
  if (!header_seen) throw InputError(path, line_no, 0, "no header line");
  if (points.empty()) throw InputError(path, line_no, 0, "no path points");
  return points;
}

}  // namespace zerog::formats
