// Typed, path-naming readers of JSON values (see json_reader.hpp).
#include "engine/scene/json_reader.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>

namespace nexdyn::scene_io {

namespace {

constexpr size_t kShownChars = 60;
constexpr size_t kMaxMessageChars = 1000;

// Appends `value` as JSON text to `out`, stopping once `out` holds more than kShownChars: a
// megabyte string or a 100,000-deep array would otherwise be dumped whole, recursively.
void show_into(const json& value, std::string& out) {
  if (out.size() > kShownChars) return;
  if (value.is_array()) {
    out += '[';
    for (size_t i = 0; i < value.size() && out.size() <= kShownChars; ++i) {
      if (i > 0) out += ',';
      show_into(value[i], out);  // each level adds a '[': the budget bounds the depth
    }
    out += ']';
  } else if (value.is_object()) {
    out += '{';
    bool first = true;
    for (const auto& item : value.items()) {
      if (out.size() > kShownChars) break;
      if (!first) out += ',';
      first = false;
      out += json(item.key()).dump() + ':';
      show_into(item.value(), out);
    }
    out += '}';
  } else {
    out += value.dump();
  }
}

// A key of the file as it appears in a key path: short keys as they are, others shown as JSON.
std::string key_text(const std::string& key) {
  bool plain = key.size() <= 40;
  for (char c : key) plain = plain && static_cast<unsigned char>(c) >= 32 && c != 127 && c != '"';
  return plain ? key : show(json(key));
}

}  // namespace

std::string show(const json& value) {
  std::string out;
  show_into(value, out);
  if (out.size() > kShownChars) out = out.substr(0, kShownChars) + "...";
  return out;
}

std::string one_line(std::string message) {
  for (char& c : message)
    if (static_cast<unsigned char>(c) < 32 || c == 127) c = '?';
  if (message.size() > kMaxMessageChars) message = message.substr(0, kMaxMessageChars) + "...";
  return message;
}

// ---- Where ---------------------------------------------------------------------------------------

Where Where::operator[](const std::string& key) const {
  return Where(file_, path_.empty() ? key_text(key) : path_ + "." + key_text(key));
}

Where Where::operator[](size_t index) const {
  return Where(file_, path_ + "[" + std::to_string(index) + "]");
}

void Where::fail(const std::string& what) const {
  throw SceneError(one_line(file_.string() + ": " + (path_.empty() ? "" : path_ + ": ") + what));
}

void Where::fail(const std::string& what, const json& value) const { fail(what + ", got " + show(value)); }

// ---- readers -------------------------------------------------------------------------------------

void check_keys(const json& object, const Where& where, std::initializer_list<const char*> allowed) {
  if (!object.is_object()) where.fail("expected an object", object);
  for (const auto& item : object.items()) {
    bool known = false;
    for (const char* key : allowed) known = known || item.key() == key;
    if (!known) {
      std::string list;
      for (const char* key : allowed) list += std::string(list.empty() ? "" : ", ") + key;
      where[item.key()].fail("unknown key (allowed here: " + list + ")");
    }
  }
}

double number(const json& value, const Where& where) {
  if (!value.is_number()) where.fail("expected a number", value);
  const double d = value.get<double>();
  if (!std::isfinite(d)) where.fail("expected a finite number", value);
  return d;
}

double positive(const json& value, const Where& where) {
  const double d = number(value, where);
  if (!(d > 0.0)) where.fail("expected a positive number", value);
  return d;
}

double non_negative(const json& value, const Where& where) {
  const double x = number(value, where);
  if (x < 0.0) where.fail("expected a number >= 0", value);
  return x;
}

int64_t integer(const json& value, const Where& where, int64_t min_value) {
  if (!value.is_number_integer()) where.fail("expected an integer", value);
  // Above INT64_MAX nlohmann keeps an unsigned number, which get<int64_t> would wrap negative.
  if (value.is_number_unsigned() && value.get<uint64_t>() > uint64_t(std::numeric_limits<int64_t>::max()))
    where.fail("expected an integer below 2^63", value);
  const int64_t i = value.get<int64_t>();
  if (i < min_value) where.fail("expected an integer >= " + std::to_string(min_value), value);
  return i;
}

int bounded_int(const json& value, const Where& where, int min_value, int max_value) {
  const int64_t i = integer(value, where, min_value);
  if (i > max_value)
    where.fail("expected an integer from " + std::to_string(min_value) + " to " + std::to_string(max_value), value);
  return static_cast<int>(i);
}

Eigen::Vector3d vec3(const json& value, const Where& where) {
  if (!value.is_array() || value.size() != 3) where.fail("expected an array of 3 numbers", value);
  return {number(value[0], where[0]), number(value[1], where[1]), number(value[2], where[2])};
}

std::string string(const json& value, const Where& where) {
  if (!value.is_string()) where.fail("expected a string", value);
  return value.get<std::string>();
}

bool boolean(const json& value, const Where& where) {
  if (!value.is_boolean()) where.fail("expected true or false", value);
  return value.get<bool>();
}

}  // namespace nexdyn::scene_io
