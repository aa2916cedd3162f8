#include "app/settings.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "core/error.h"
#include "core/fs.h"

namespace snow::app {
namespace {

using nlohmann::json;

std::pair<std::string, std::string> split_key(const std::string& key) {
  const size_t dot = key.find('.');
  return {key.substr(0, dot), key.substr(dot + 1)};
}

json to_json_value(const glm::vec2& v) { return json::array({v.x, v.y}); }
template <class T>
json to_json_value(const T& v) {
  return json(v);
}

void from_json_value(const json& j, glm::vec2& v) {
  if (!j.is_array() || j.size() != 2 || !j[0].is_number() || !j[1].is_number()) {
    throw json::type_error::create(302, "expected [x, z]", &j);
  }
  v = glm::vec2(j[0].get<float>(), j[1].get<float>());
}
void from_json_value(const json& j, bool& v) { v = j.get<bool>(); }
void from_json_value(const json& j, std::string& v) { v = j.get<std::string>(); }
void from_json_value(const json& j, std::vector<std::string>& v) {
  v = j.get<std::vector<std::string>>();
}
template <class T>
void from_json_value(const json& j, T& v) {
  if (!j.is_number()) throw json::type_error::create(302, "expected a number", &j);
  if constexpr (std::is_integral_v<T>) {
    // A whole number that T holds: nlohmann's get<T> would wrap the others.
    const bool fits =
        j.is_number_unsigned() ? j.get<uint64_t>() <= uint64_t(std::numeric_limits<T>::max())
        : j.is_number_integer()
            ? std::is_signed_v<T> && j.get<int64_t>() >= int64_t(std::numeric_limits<T>::min())
            : false;
    if (!fits) throw json::type_error::create(302, "expected a whole number", &j);
  }
  v = j.get<T>();
}

/// The number as the messages print it: up to 15 significant digits.
std::string number_text(double v) {
  char text[40];
  std::snprintf(text, sizeof text, "%.15g", v);
  return text;
}

/// CLI11 reads unsigned options with strtoull, which takes "-1" as its
/// largest value and saturates past it: "" for a whole number within
/// uint64_t, else the reason.
std::string unsigned_text_error(const std::string& text) {
  if (text.find('-') != std::string::npos)
    return "expected a whole number >= 0, got '" + text + "'";
  errno = 0;
  char* end = nullptr;
  std::strtoull(text.c_str(), &end, 0);
  if (errno == ERANGE)
    return "expected a whole number up to " + std::to_string(std::numeric_limits<uint64_t>::max()) +
           ", got '" + text + "'";
  return {};
}

// CLI11 parses "X,Z" into glm::vec2 through this lexical cast.
bool parse_vec2(const std::string& text, glm::vec2& out) {
  std::istringstream in(text);
  char comma = 0;
  float x = 0, z = 0;
  if (!(in >> x >> comma >> z) || comma != ',' || !(in >> std::ws).eof()) return false;
  out = glm::vec2(x, z);
  return true;
}

}  // namespace

std::string range_text(const Range& range) {
  if (!(range.hi > range.lo)) return {};
  return std::string("[") + (range.negative_auto ? "negative, or " : "") + number_text(range.lo) +
         ".." + number_text(range.hi) + "]";
}

void check_range(const std::string& flag, const std::string& key, double value, const Range& range,
                 bool float_field) {
  if (!(range.hi > range.lo)) return;
  // A float field holds a bound typed as it is rounded to float ("0.01" is
  // a little under 0.01): it is compared with the bound rounded alike.
  const double lo = float_field ? double(float(range.lo)) : range.lo;
  const double hi = float_field ? double(float(range.hi)) : range.hi;
  if (std::isfinite(value) &&
      ((value >= lo && value <= hi) || (range.negative_auto && value < 0))) {
    return;
  }
  throw InputError(flag + (key.empty() ? "" : " (" + key + ")") + " must be " +
                   (range.negative_auto ? "negative (automatic) or " : "") + "in " +
                   number_text(range.lo) + ".." + number_text(range.hi) + ", got " +
                   number_text(value));
}

void check_settings(const PipelineSettings& settings) {
  PipelineSettings copy = settings;
  visit_settings(
      [&](const char* key, const char* flag, const char*, const auto& field, const Range& range) {
        using T = std::decay_t<decltype(field)>;
        constexpr bool is_float = std::is_same_v<T, float> || std::is_same_v<T, glm::vec2>;
        if constexpr (std::is_same_v<T, glm::vec2>) {
          check_range(flag, key, field.x, range, is_float);
          check_range(flag, key, field.y, range, is_float);
        } else if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
          check_range(flag, key, double(field), range, is_float);
        }
      },
      copy);
}

FileFrame file_frame(const PipelineSettings& s) {
  FileFrame frame;
  frame.unit_scale = s.unit_scale;
  frame.z_up = z_up_from_name(s.up);
  return frame;
}

void resolve_snow_settings(PipelineSettings& s) {
  s.stabilize.cohesion = cohesion_of(snow_kind_from_name(s.snow_kind));
  if (s.stand_height >= 0.0f) s.stabilize.cohesion.stand_height = s.stand_height;
  if (s.hold_depth >= 0.0f) s.stabilize.cohesion.hold_depth = s.hold_depth;
  s.accumulate.drift = drift_for_wind(s.wind_transport ? s.coverage.wind : glm::vec2(0.0f),
                                      snow_kind_from_name(s.snow_kind), s.accumulate.fall_depth);
  const DriftSettings& drift = s.accumulate.drift;
  s.polygonize.cornice = Cornice{};
  if (drift.transport > 0.0f) {
    s.polygonize.cornice.direction = glm::normalize(drift.direction);
    s.polygonize.cornice.length = float(plan::cornice_length(double(drift.transport)));
  }
}

plan::Settings plan_settings(const PipelineSettings& settings) {
  plan::Settings out;
  out.fall_depth = settings.accumulate.fall_depth;
  out.texel = settings.peel.texel;
  out.max_side = settings.peel.max_side;
  out.peel_device = settings.peel.device;
  out.coverage_method = settings.coverage.method;
  out.stabilizer = settings.stabilize.device;
  return out;
}

json settings_to_json(const PipelineSettings& settings) {
  json out = json::object();
  PipelineSettings copy = settings;
  visit_settings(
      [&](const char* key, const char*, const char*, auto& field, const Range&) {
        auto [group, name] = split_key(key);
        out[group][name] = to_json_value(field);
      },
      copy);
  return out;
}

void settings_from_json(const json& input, PipelineSettings& settings) {
  const json& root = input.contains("settings") ? input.at("settings") : input;
  if (!root.is_object()) throw InputError("settings: expected a JSON object");
  // Every key in the file must be known.
  json known = settings_to_json(settings);
  for (const auto& [group, members] : root.items()) {
    if (!known.contains(group) || !members.is_object()) {
      throw InputError("settings: unknown group '" + group + "'");
    }
    for (const auto& [name, value] : members.items()) {
      if (!known[group].contains(name))
        throw InputError("settings: unknown key '" + group + "." + name + "'");
    }
  }
  visit_settings(
      [&](const char* key, const char*, const char*, auto& field, const Range&) {
        auto [group, name] = split_key(key);
        if (!root.contains(group) || !root[group].contains(name)) return;
        try {
          from_json_value(root[group][name], field);
        } catch (const json::exception& e) {
          // e.what() is "[json.exception...] what was expected".
          const std::string why = e.what();
          const size_t at = why.find("] ");
          throw InputError(std::string("settings: '") + key + "' has a value of the wrong type (" +
                           root[group][name].dump() + "; " +
                           (at == std::string::npos ? why : why.substr(at + 2)) + ")");
        }
      },
      settings);
}

void load_settings_file(const std::string& path, PipelineSettings& settings) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  json j = json::parse(bytes.begin(), bytes.end(), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw InputError(path + ": not valid JSON");
  try {
    settings_from_json(j, settings);
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

bool is_developer_setting(const std::string& key) {
  static const char* const kDeveloper[] = {
      "maps.merge_distance", "maps.device",          "coverage.batch",     "coverage.bias",
      "coverage.method",     "snow.min_move",        "snow.max_stride",    "snow.adaptive_stride",
      "snow.device",         "snow.route_steep",     "snow.deposit_piles", "snow.drain_edges",
      "snow.route_creep",    "mesh.piece_triangles", "snow.stand_height",  "snow.hold_depth",
      "snow.wind_transport"};
  for (const char* k : kDeveloper) {
    if (key == k) return true;
  }
  return false;
}

void add_settings_options(CLI::App& cmd, PipelineSettings& settings, bool show_developer) {
  visit_settings(
      [&](const char* key, const char* flag, const char* help_text, auto& field,
          const Range& range) {
        using T = std::decay_t<decltype(field)>;
        const std::string bounds = range_text(range);
        const std::string help = bounds.empty() ? help_text : help_text + (" " + bounds);
        const std::string group = split_key(key).first;
        const std::string section =
            is_developer_setting(key) ? (show_developer ? "Developer (backends and speed-ups)" : "")
            : group == "maps"         ? "Maps"
            : group == "coverage"     ? "Coverage"
            : group == "snow"         ? "Snowfall and sliding"
            : group == "mesh"         ? "Meshes"
            : group == "weather"      ? "Weather over time"
            : group == "tracks"       ? "Tracks in the snow"
                                      : "Object filters";
        CLI::Option* opt = nullptr;
        if constexpr (std::is_same_v<T, glm::vec2>) {
          opt = cmd.add_option_function<std::string>(
              flag,
              [&field, flag](const std::string& text) {
                if (!parse_vec2(text, field)) {
                  throw CLI::ValidationError(flag,
                                             "expected X,Z (two numbers), got '" + text + "'");
                }
              },
              help);
          opt->default_str(std::to_string(field.x) + "," + std::to_string(field.y));
        } else {
          opt = cmd.add_option(flag, field, help)->capture_default_str();
          // CLI11 would take "-1" for an unsigned field as its largest
          // value, and 2^64 as 2^64 - 1.
          if constexpr (std::is_unsigned_v<T> && !std::is_same_v<T, bool>) {
            opt->check(CLI::Validator(unsigned_text_error, "NONNEGATIVE"));
          }
        }
        opt->group(section);
      },
      settings);
}

}  // namespace snow::app
