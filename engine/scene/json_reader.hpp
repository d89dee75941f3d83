// The strict JSON reader under the scene loader: typed value readers that throw SceneError with
// the file and the key path of the value in every message.
//
// A value is always read together with its Where, the key path leading to it from the root of
// the file ("bodies[1].box.cells"), so that a reader deep inside the scene can fail with
//   "scenes/drop.json: bodies[1].box.cells[2]: expected an integer >= 1, got 0".
// Messages are one line of bounded length whatever the file holds: shown values are cut to about
// 60 characters and control characters become '?'. Nothing here knows what a scene means; the
// settings readers (settings_readers.hpp) and the model builder (build_model.hpp) do.
#pragma once

#include "engine/scene/scene_error.hpp"

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <utility>

namespace nexdyn::scene_io {

using nlohmann::json;

// `value` as JSON text, at most about 60 characters ("..." marks a cut).
std::string show(const json& value);

// `message` on one line (control characters as '?') and at most about 1000 characters.
std::string one_line(std::string message);

// Where in the file a value sits, for error messages: the file and the key path.
class Where {
 public:
  // `file` must outlive the Where and every Where made from it.
  Where(const std::filesystem::path& file, std::string path) : file_(file), path_(std::move(path)) {}
  Where operator[](const std::string& key) const;  // a member: "a.key"
  Where operator[](size_t index) const;            // an array element: "a[3]"
  // Throws SceneError "<file>: <path>: <what>" (no path part at the root).
  [[noreturn]] void fail(const std::string& what) const;
  // The same, followed by ", got <value>".
  [[noreturn]] void fail(const std::string& what, const json& value) const;

 private:
  const std::filesystem::path& file_;
  std::string path_;
};

// Fails unless `object` is an object whose keys are all in `allowed` (the message lists them).
void check_keys(const json& object, const Where& where, std::initializer_list<const char*> allowed);

// Typed readers: each returns the value or fails at `where` saying what was expected.
double number(const json& value, const Where& where);        // finite
double positive(const json& value, const Where& where);      // finite, > 0
double non_negative(const json& value, const Where& where);  // finite, >= 0
int64_t integer(const json& value, const Where& where, int64_t min_value);  // below 2^63
// An integer stored in an int: bounded before the cast, so that 2^32 + 1 cannot become 1.
int bounded_int(const json& value, const Where& where, int min_value, int max_value);
Eigen::Vector3d vec3(const json& value, const Where& where);  // [x, y, z], finite
std::string string(const json& value, const Where& where);
bool boolean(const json& value, const Where& where);

}  // namespace nexdyn::scene_io
