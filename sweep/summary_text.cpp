#include "sweep/summary_text.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace locaid::sweep::summary_text {

std::string Fmt(std::optional<double> v) {
  if (!v) return "";
  std::ostringstream s;
  s.precision(17);
  s << *v;
  double back = 0;
  for (int p = 6; p <= 17; ++p) {  // fewer digits where they round-trip
    std::ostringstream t;
    t.precision(p);
    t << *v;
    std::istringstream(t.str()) >> back;
    if (back == *v) return t.str();
  }
  return s.str();
}

std::string Csv(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (const char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return out + "\"";
}

std::ofstream Open(const std::filesystem::path& file) {
  std::ofstream out(file);
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
  return out;
}

std::string CountsText(const std::map<std::string, int64_t>& counts) {
  std::string out;
  for (const auto& [name, n] : counts) {
    if (!out.empty()) out += ", ";
    out += name + " " + std::to_string(n);
  }
  return out.empty() ? "-" : out;
}

std::string CsvTriple(const Distribution& d) {
  if (d.n == 0) return ",,";
  return Fmt(d.median) + "," + Fmt(d.p90) + "," + Fmt(d.max);
}

std::string TripleHeader(const std::string& name) { return name + "_median," + name + "_p90," + name + "_max"; }

double Round(double v, int digits) {
  const double scale = std::pow(10.0, digits);
  return std::round(v * scale) / scale;
}

std::string MdTriple(const Distribution& d, int digits) {
  if (d.n == 0) return "-";
  return Fmt(Round(d.median, digits)) + " / " + Fmt(Round(d.p90, digits)) + " / " + Fmt(Round(d.max, digits));
}

}  // namespace locaid::sweep::summary_text
