#include "vdrig/rti/light_positions.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include "vdrig/core/file_read.hpp"

namespace vdrig::rti {
namespace {

namespace fs = std::filesystem;

constexpr size_t kMaxLpBytes = 16u << 20;

Error corrupt(int line, const std::string& why) {
  return make_error(ErrorCode::kCorrupt, ".lp line " + std::to_string(line) + ": " + why);
}

/// The fields of a line split on whitespace.
std::vector<std::string> fields(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string f; in >> f;) out.push_back(f);
  return out;
}

bool parse_double(const std::string& text, double* value) {
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return end && *end == '\0' && end != text.c_str();
}

/// The image a name in the .lp refers to: relative names beside the .lp; a path that does not exist as written
/// (typically a Windows path from the dome's PC) by its last component beside the .lp.
fs::path resolve_image(const std::string& name, const fs::path& folder) {
  const fs::path as_written = fs::path(name).is_absolute() ? fs::path(name) : folder / name;
  std::error_code ec;
  if (fs::exists(as_written, ec)) return as_written;
  const size_t cut = name.find_last_of("/\\");
  return cut == std::string::npos ? as_written : folder / name.substr(cut + 1);
}

}  // namespace

Result<std::vector<LightPosition>> parse_light_positions(const std::string& text, const fs::path& folder) {
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  long count = -1;
  std::vector<LightPosition> lights;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::vector<std::string> f = fields(line);
    if (f.empty()) continue;
    if (count < 0) {
      char* end = nullptr;
      count = std::strtol(f[0].c_str(), &end, 10);
      if (f.size() != 1 || *end != '\0' || count <= 0 || count > 100000)
        return corrupt(line_no, "the first line must be the image count, got \"" + line + "\"");
      continue;
    }
    if (f.size() < 4) return corrupt(line_no, "expected \"FILENAME X Y Z\", got \"" + line + "\"");
    Vec3d d;
    for (int i = 0; i < 3; ++i)
      if (!parse_double(f[f.size() - 3 + i], &d[i]) || !std::isfinite(d[i]))
        return corrupt(line_no, "\"" + f[f.size() - 3 + i] + "\" is not a number");
    const double norm = d.norm();
    if (!(norm > 1e-9)) return corrupt(line_no, "zero light direction");
    // The name is the line up to the first of the three numbers (names may contain spaces).
    size_t cut = line.size();
    for (int i = 0; i < 3; ++i) {
      cut = line.find_last_not_of(" \t", cut - 1);
      cut = line.find_last_of(" \t", cut);
    }
    const size_t first = line.find_first_not_of(" \t");
    const std::string name = line.substr(first, line.find_last_not_of(" \t", cut) + 1 - first);
    lights.push_back({resolve_image(name, folder), d / norm});
  }
  if (count < 0) return make_error(ErrorCode::kCorrupt, ".lp file is empty");
  if (static_cast<long>(lights.size()) != count)
    return make_error(ErrorCode::kCorrupt, ".lp count line says " + std::to_string(count) + ", the file lists " +
                                               std::to_string(lights.size()) + " images");
  return lights;
}

Result<std::vector<LightPosition>> read_light_positions(const fs::path& lp_file) {
  auto text = read_regular_file(lp_file, kMaxLpBytes);
  if (!text) return text.error();
  auto lights = parse_light_positions(text.value(), lp_file.parent_path());
  if (!lights) return make_error(lights.error().code, lp_file.string() + ": " + lights.error().message);
  return lights;
}

Result<fs::path> find_light_positions(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return make_error(ErrorCode::kNotFound, path.string() + " does not exist");
  if (!fs::is_directory(path, ec)) return path;
  std::vector<fs::path> found;
  for (const auto& e : fs::directory_iterator(path, ec))
    if (e.is_regular_file() && e.path().extension() == ".lp") found.push_back(e.path());
  if (found.empty()) return make_error(ErrorCode::kNotFound, "no .lp file in " + path.string());
  if (found.size() > 1) {
    std::string names;
    for (const auto& p : found) names += " " + p.filename().string();
    return make_error(ErrorCode::kInvalidArgument, "several .lp files in " + path.string() + ":" + names);
  }
  return found.front();
}

}  // namespace vdrig::rti
