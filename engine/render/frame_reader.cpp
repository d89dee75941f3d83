// VTU and PVD readers for our own output (see frame_reader.hpp).
#include "engine/render/frame_reader.hpp"

#include "engine/mesh/mesh_file.hpp"

#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace {

[[noreturn]] void fail(std::string_view name, const std::string& what) {
  throw std::runtime_error(std::string(name) + ": " + what);
}

// The value of attribute `key` in the XML element text `element` ("" when absent).
std::string attribute(std::string_view element, std::string_view key) {
  const std::string pattern = " " + std::string(key) + "=\"";
  const size_t start = element.find(pattern);
  if (start == std::string_view::npos) return "";
  const size_t begin = start + pattern.size();
  const size_t end = element.find('"', begin);
  if (end == std::string_view::npos) return "";
  return std::string(element.substr(begin, end - begin));
}

// The <DataArray .../> element named `name`.
std::string_view data_array(std::string_view xml, std::string_view name, std::string_view file) {
  const std::string key = "Name=\"" + std::string(name) + "\"";
  for (size_t at = xml.find("<DataArray"); at != std::string_view::npos; at = xml.find("<DataArray", at + 1)) {
    const size_t end = xml.find('>', at);
    if (end == std::string_view::npos) break;
    const std::string_view element = xml.substr(at, end - at + 1);
    if (element.find(key) != std::string_view::npos) return element;
  }
  fail(file, "no DataArray \"" + std::string(name) + "\"");
}

// Copies the appended block of array `name` into `out`, checking its type and that its size is
// `expected` values (or any multiple of `multiple` when expected < 0).
template <typename T>
void read_block(std::string_view xml, std::string_view data, std::string_view name, const char* type,
                int64_t expected, int64_t multiple, std::vector<T>& out, std::string_view file) {
  const std::string_view element = data_array(xml, name, file);
  if (attribute(element, "type") != type)
    fail(file, "DataArray \"" + std::string(name) + "\" is not of type " + type);
  const std::string offset_text = attribute(element, "offset");
  uint64_t offset = 0;
  try {
    size_t used = 0;
    offset = std::stoull(offset_text, &used);
    if (used != offset_text.size()) throw std::invalid_argument("");
  } catch (const std::exception&) {
    fail(file, "DataArray \"" + std::string(name) + "\" has a bad offset \"" + offset_text + "\"");
  }
  uint64_t bytes = 0;
  if (offset > data.size() || data.size() - offset < sizeof bytes)
    fail(file, "DataArray \"" + std::string(name) + "\" lies past the end of the file (truncated?)");
  std::memcpy(&bytes, data.data() + offset, sizeof bytes);
  if (bytes % sizeof(T) != 0 || bytes > data.size() - offset - sizeof bytes)
    fail(file, "DataArray \"" + std::string(name) + "\" lies past the end of the file (truncated?)");
  const int64_t count = static_cast<int64_t>(bytes / sizeof(T));
  if ((expected >= 0 && count != expected) || (expected < 0 && count % multiple != 0))
    fail(file, "DataArray \"" + std::string(name) + "\" has " + std::to_string(count) + " values");
  out.resize(static_cast<size_t>(count));
  if (count > 0) std::memcpy(out.data(), data.data() + offset + sizeof bytes, bytes);
}

}  // namespace

FrameData parse_vtu_frame(std::string_view bytes, std::string_view name) {
  const std::string_view marker = "<AppendedData encoding=\"raw\">";
  const size_t appended = bytes.find(marker);
  if (bytes.find("<VTKFile type=\"UnstructuredGrid\"") == std::string_view::npos || appended == std::string_view::npos)
    fail(name, "not a VTU frame written by nexdyn (no UnstructuredGrid with raw appended data)");
  if (bytes.find("header_type=\"UInt64\"") == std::string_view::npos)
    fail(name, "expected header_type=\"UInt64\"");
  const size_t underscore = bytes.find('_', appended + marker.size());
  if (underscore == std::string_view::npos) fail(name, "appended data has no '_' start mark");
  const std::string_view xml = bytes.substr(0, appended);
  const std::string_view data = bytes.substr(underscore + 1);

  const size_t piece = xml.find("<Piece");
  if (piece == std::string_view::npos) fail(name, "no <Piece>");
  const std::string_view piece_element = xml.substr(piece, xml.find('>', piece) - piece + 1);
  int64_t num_points = -1, num_cells = -1;
  try {
    num_points = std::stoll(attribute(piece_element, "NumberOfPoints"));
    num_cells = std::stoll(attribute(piece_element, "NumberOfCells"));
  } catch (const std::exception&) {
    fail(name, "<Piece> lacks NumberOfPoints or NumberOfCells");
  }
  if (num_points < 0 || num_cells < 0 || num_points > (int64_t{1} << 31) / 3 || num_cells > (int64_t{1} << 31) / 4)
    fail(name, "<Piece> has impossible counts");

  FrameData frame;
  read_block(xml, data, "Points", "Float64", 3 * num_points, 0, frame.points, name);
  // MPM runs write particle clouds: vertex cells and a "radius" per point, no tets.
  if (xml.find("Name=\"radius\"") != std::string_view::npos) {
    read_block(xml, data, "radius", "Float64", num_points, 0, frame.radius, name);
    for (double r : frame.radius)
      if (!(r > 0.0) || !std::isfinite(r)) fail(name, "a particle radius is not a positive number");
  } else {
    read_block(xml, data, "connectivity", "Int32", 4 * num_cells, 0, frame.tets, name);
  }
  read_block(xml, data, "velocity", "Float64", 3 * num_points, 0, frame.velocity, name);
  read_block(xml, data, "body", "Int32", num_points, 0, frame.body, name);
  for (size_t i = 0; i < frame.tets.size(); ++i)
    if (frame.tets[i] < 0 || frame.tets[i] >= num_points)
      fail(name, "tet " + std::to_string(i / 4) + " names point " + std::to_string(frame.tets[i]) + " of " +
                     std::to_string(num_points));
  return frame;
}

FrameData read_vtu_frame(const std::filesystem::path& file) {
  std::string bytes;
  try {
    bytes = read_mesh_file(file);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string(e.what()) + " (a frame listed in scene.pvd)");
  }
  return parse_vtu_frame(bytes, file.string());
}

std::vector<FrameEntry> read_frame_list(const std::filesystem::path& run_dir) {
  const std::filesystem::path pvd = run_dir / "scene.pvd";
  std::error_code error;
  if (!std::filesystem::is_regular_file(pvd, error))
    throw std::runtime_error(pvd.string() + ": no such file (is " + run_dir.string() +
                             " the output folder of `nexdyn run` with VTU frames?)");
  const std::string text = read_mesh_file(pvd);
  std::vector<FrameEntry> frames;
  for (size_t at = text.find("<DataSet"); at != std::string::npos; at = text.find("<DataSet", at + 1)) {
    const std::string_view element(text.data() + at, text.find('>', at) - at + 1);
    FrameEntry entry;
    const std::string file = attribute(element, "file");
    try {
      entry.time = std::stod(attribute(element, "timestep"));
    } catch (const std::exception&) {
      fail(pvd.string(), "a DataSet has no timestep");
    }
    const size_t digits = file.rfind("frame_");
    if (file.empty() || digits == std::string::npos)
      fail(pvd.string(), "DataSet file \"" + file + "\" is not frames/frame_NNNNNN.vtu");
    try {
      entry.number = std::stoll(file.substr(digits + 6));
    } catch (const std::exception&) {
      fail(pvd.string(), "DataSet file \"" + file + "\" is not frames/frame_NNNNNN.vtu");
    }
    entry.file = run_dir / file;
    frames.push_back(entry);
  }
  if (frames.empty()) fail(pvd.string(), "lists no frame");
  return frames;
}

}  // namespace nexdyn
