// The glTF schema's minimums, maximums and enumerations for indices,
// offsets, strides, counts and enum values, checked on the JSON text
// itself. tinygltf drops a value of the wrong kind (a negative byteOffset,
// a fractional count, a string where a number belongs) as if it were
// absent and uses the default, so the Model it returns cannot tell: a
// bufferView at byteOffset -4 rendered as if it were at 0.
//
// One pass over the text with a path of keys ("*" for array items), no
// document in memory (a .gltf with embedded buffers is mostly one long
// string). Malformed JSON is left to tinygltf to explain. Where the schema
// leaves a value open to extensions (an image's mimeType: image/ktx2,
// image/vnd-ms.dds), so does this.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/util/errors.h"
#include "scenes/gltf_internal.h"

namespace tandem::gltf {

namespace {

struct Rule {
  const char* path;  // '/'-separated; "*" matches any one key or array item
  enum Kind { kIndex, kCount, kIntRange, kIntSet, kPositive, kNonNegative, kStringSet } kind;
  std::vector<double> numbers = {};  // kIntRange: {min, max}; kIntSet: the values
  std::vector<const char*> strings = {};
};

const std::vector<Rule>& rules() {
  static const std::vector<Rule> r = {
      {"scene", Rule::kIndex},
      {"scenes/*/nodes/*", Rule::kIndex},
      {"nodes/*/camera", Rule::kIndex},
      {"nodes/*/skin", Rule::kIndex},
      {"nodes/*/mesh", Rule::kIndex},
      {"nodes/*/children/*", Rule::kIndex},
      {"nodes/*/extensions/KHR_lights_punctual/light", Rule::kIndex},
      {"nodes/*/extensions/EXT_mesh_gpu_instancing/attributes/*", Rule::kIndex},
      {"meshes/*/primitives/*/indices", Rule::kIndex},
      {"meshes/*/primitives/*/material", Rule::kIndex},
      {"meshes/*/primitives/*/mode", Rule::kIntRange, {0, 6}},
      {"meshes/*/primitives/*/attributes/*", Rule::kIndex},
      {"meshes/*/primitives/*/targets/*/*", Rule::kIndex},
      {"accessors/*/bufferView", Rule::kIndex},
      {"accessors/*/byteOffset", Rule::kIndex},
      {"accessors/*/componentType", Rule::kIntSet, {5120, 5121, 5122, 5123, 5125, 5126}},
      {"accessors/*/count", Rule::kCount},
      {"accessors/*/type",
       Rule::kStringSet,
       {},
       {"SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"}},
      {"accessors/*/sparse/count", Rule::kCount},
      {"accessors/*/sparse/indices/bufferView", Rule::kIndex},
      {"accessors/*/sparse/indices/byteOffset", Rule::kIndex},
      {"accessors/*/sparse/indices/componentType", Rule::kIntSet, {5121, 5123, 5125}},
      {"accessors/*/sparse/values/bufferView", Rule::kIndex},
      {"accessors/*/sparse/values/byteOffset", Rule::kIndex},
      {"bufferViews/*/buffer", Rule::kIndex},
      {"bufferViews/*/byteOffset", Rule::kIndex},
      {"bufferViews/*/byteLength", Rule::kCount},
      {"bufferViews/*/byteStride", Rule::kIntRange, {4, 252}},
      {"bufferViews/*/target", Rule::kIntSet, {34962, 34963}},
      {"buffers/*/byteLength", Rule::kCount},
      {"images/*/bufferView", Rule::kIndex},
      {"textures/*/sampler", Rule::kIndex},
      {"textures/*/source", Rule::kIndex},
      {"samplers/*/magFilter", Rule::kIntSet, {9728, 9729}},
      {"samplers/*/minFilter", Rule::kIntSet, {9728, 9729, 9984, 9985, 9986, 9987}},
      {"samplers/*/wrapS", Rule::kIntSet, {33071, 33648, 10497}},
      {"samplers/*/wrapT", Rule::kIntSet, {33071, 33648, 10497}},
      {"skins/*/inverseBindMatrices", Rule::kIndex},
      {"skins/*/skeleton", Rule::kIndex},
      {"skins/*/joints/*", Rule::kIndex},
      {"animations/*/channels/*/sampler", Rule::kIndex},
      {"animations/*/channels/*/target/node", Rule::kIndex},
      {"animations/*/channels/*/target/path",
       Rule::kStringSet,
       {},
       {"translation", "rotation", "scale", "weights", "pointer"}},
      {"animations/*/samplers/*/input", Rule::kIndex},
      {"animations/*/samplers/*/output", Rule::kIndex},
      {"animations/*/samplers/*/interpolation",
       Rule::kStringSet,
       {},
       {"LINEAR", "STEP", "CUBICSPLINE"}},
      {"cameras/*/type", Rule::kStringSet, {}, {"perspective", "orthographic"}},
      {"cameras/*/perspective/yfov", Rule::kPositive},
      {"cameras/*/perspective/znear", Rule::kPositive},
      {"cameras/*/perspective/zfar", Rule::kPositive},
      {"cameras/*/perspective/aspectRatio", Rule::kPositive},
      {"cameras/*/orthographic/znear", Rule::kNonNegative},
      {"cameras/*/orthographic/zfar", Rule::kPositive},
      {"materials/*/alphaMode", Rule::kStringSet, {}, {"OPAQUE", "MASK", "BLEND"}},
      {"materials/*/alphaCutoff", Rule::kNonNegative},
      // Texture references: in the core slots, pbrMetallicRoughness and
      // every material extension.
      {"materials/*/*/index", Rule::kIndex},
      {"materials/*/*/texCoord", Rule::kIndex},
      {"materials/*/pbrMetallicRoughness/*/index", Rule::kIndex},
      {"materials/*/pbrMetallicRoughness/*/texCoord", Rule::kIndex},
      {"materials/*/extensions/*/*/index", Rule::kIndex},
      {"materials/*/extensions/*/*/texCoord", Rule::kIndex},
      {"extensions/KHR_lights_punctual/lights/*/type",
       Rule::kStringSet,
       {},
       {"directional", "point", "spot"}},
      {"extensions/KHR_lights_punctual/lights/*/intensity", Rule::kNonNegative},
      {"extensions/KHR_lights_punctual/lights/*/range", Rule::kPositive},
  };
  return r;
}

// The JSON scanner: values are only looked at where a rule's path matches.
class Scanner {
 public:
  Scanner(const char* text, size_t size, const std::string& label)
      : p_(text), end_(text + size), label_(label) {}

  // False when the JSON is malformed (tinygltf then explains); throws
  // InputError for a value the schema forbids.
  bool run() {
    skip_space();
    if (!value()) return false;
    skip_space();
    return p_ == end_;
  }

 private:
  void skip_space() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\n' || *p_ == '\r'))
      ++p_;
  }

  // The raw text of a string (without its quotes), with the simple escapes
  // undone; p_ at the opening quote.
  bool string(std::string* out) {
    if (p_ >= end_ || *p_ != '"') return false;
    ++p_;
    while (p_ < end_ && *p_ != '"') {
      if (*p_ == '\\') {
        if (++p_ >= end_) return false;
        const char c = *p_;
        if (out != nullptr) {
          const char* simple = "\"\\/bfnrt";
          const char* decoded = "\"\\/\b\f\n\r\t";
          const char* at = std::strchr(simple, c);
          if (c == 'u' || at == nullptr) {
            out->push_back('?');  // no enum value holds one
          } else {
            out->push_back(decoded[at - simple]);
          }
        }
        if (c == 'u') p_ += 4;
        ++p_;
        continue;
      }
      if (out != nullptr) out->push_back(*p_);
      ++p_;
    }
    if (p_ >= end_) return false;
    ++p_;
    return true;
  }

  const Rule* rule_here() const {
    // Extras are the application's own data: the schema says nothing of them.
    for (size_t i = 0; i < path_.size(); ++i)
      if (!is_index_[i] && path_[i] == "extras") return nullptr;
    if (path_.size() > 7) return nullptr;
    for (const Rule& r : rules()) {
      const char* pattern = r.path;
      size_t segment = 0;
      bool match = true;
      while (*pattern != '\0' && match) {
        const char* slash = std::strchr(pattern, '/');
        const size_t n = slash ? size_t(slash - pattern) : std::strlen(pattern);
        if (segment >= path_.size()) {
          match = false;
        } else if (!(n == 1 && pattern[0] == '*') &&
                   path_[segment].compare(0, std::string::npos, pattern, n) != 0) {
          match = false;
        }
        ++segment;
        pattern += n + (slash ? 1 : 0);
      }
      if (match && segment == path_.size()) return &r;
    }
    return nullptr;
  }

  // "accessors[3].sparse.indices.byteOffset" for messages.
  std::string where() const {
    std::string out;
    for (size_t i = 0; i < path_.size(); ++i) {
      if (is_index_[i]) {
        out += "[" + path_[i] + "]";
      } else {
        out += (out.empty() ? "" : ".") + path_[i].substr(0, 80);
      }
    }
    return out;
  }

  [[noreturn]] void refuse(const std::string& value, const std::string& requirement) const {
    throw InputError(label_ + ": " + where() + " is " + value + "; the glTF schema requires " +
                     requirement);
  }

  void check_number(const Rule& r, const std::string& text) const {
    const double v = std::strtod(text.c_str(), nullptr);
    const bool integer =
        std::isfinite(v) && v == std::floor(v) && std::fabs(v) <= 9007199254740992.0;
    switch (r.kind) {
      case Rule::kIndex:
        if (!integer || v < 0) refuse(text, "an integer >= 0");
        return;
      case Rule::kCount:
        if (!integer || v < 1) refuse(text, "an integer >= 1");
        return;
      case Rule::kIntRange:
        if (!integer || v < r.numbers[0] || v > r.numbers[1]) {
          refuse(text, "an integer in " + std::to_string(int64_t(r.numbers[0])) + ".." +
                           std::to_string(int64_t(r.numbers[1])));
        }
        return;
      case Rule::kIntSet:
        for (double allowed : r.numbers)
          if (integer && v == allowed) return;
        refuse(text, "one of " + set_text(r));
      case Rule::kPositive:
        if (!(v > 0.0) || !std::isfinite(v)) refuse(text, "a number > 0");
        return;
      case Rule::kNonNegative:
        if (!(v >= 0.0) || !std::isfinite(v)) refuse(text, "a number >= 0");
        return;
      case Rule::kStringSet:
        refuse(text, "one of " + set_text(r));
    }
  }

  static std::string set_text(const Rule& r) {
    std::string out;
    for (double n : r.numbers)
      out += (out.empty() ? "" : ", ") + std::to_string(int64_t(n));
    for (const char* s : r.strings)
      out += (out.empty() ? "\"" : ", \"") + std::string(s) + "\"";
    return out;
  }

  static const char* kind_text(const Rule& r) {
    switch (r.kind) {
      case Rule::kIndex:
        return "an integer >= 0";
      case Rule::kCount:
        return "an integer >= 1";
      case Rule::kIntRange:
      case Rule::kIntSet:
        return "an integer";
      case Rule::kPositive:
        return "a number > 0";
      case Rule::kNonNegative:
        return "a number >= 0";
      case Rule::kStringSet:
        return "a string";
    }
    return "";
  }

  bool value() {
    if (p_ >= end_) return false;
    const Rule* rule = path_.empty() ? nullptr : rule_here();
    const char c = *p_;
    if (c == '{' || c == '[') {
      if (rule != nullptr) refuse(c == '{' ? "an object" : "an array", kind_text(*rule));
      return container(c == '{' ? '}' : ']');
    }
    if (c == '"') {
      std::string text;
      const char* start = p_;
      if (!string(rule != nullptr ? &text : nullptr)) return false;
      if (rule == nullptr) return true;
      if (rule->kind != Rule::kStringSet)
        refuse(std::string(start, size_t(std::min<ptrdiff_t>(p_ - start, 60))), kind_text(*rule));
      for (const char* s : rule->strings)
        if (text == s) return true;
      refuse("\"" + text.substr(0, 60) + "\"", "one of " + set_text(*rule));
    }
    // A number, true, false or null.
    const char* start = p_;
    while (p_ < end_ && *p_ != ',' && *p_ != '}' && *p_ != ']' && *p_ != ' ' && *p_ != '\n' &&
           *p_ != '\r' && *p_ != '\t')
      ++p_;
    if (p_ == start) return false;
    if (rule == nullptr) return true;
    const std::string text(start, size_t(p_ - start));
    const bool number = text[0] == '-' || (text[0] >= '0' && text[0] <= '9');
    if (!number || rule->kind == Rule::kStringSet) refuse(text.substr(0, 60), kind_text(*rule));
    check_number(*rule, text);
    return true;
  }

  // An object ('{', keyed members) or an array ('[', items named by index).
  bool container(char close) {
    const bool keyed = close == '}';
    ++p_;
    skip_space();
    if (p_ < end_ && *p_ == close) return ++p_, true;
    for (size_t i = 0;; ++i) {
      skip_space();
      std::string name = keyed ? std::string() : std::to_string(i);
      if (keyed) {
        if (!string(&name)) return false;
        skip_space();
        if (p_ >= end_ || *p_ != ':') return false;
        ++p_;
        skip_space();
      }
      path_.push_back(std::move(name));
      is_index_.push_back(!keyed);
      const bool ok = value();
      path_.pop_back();
      is_index_.pop_back();
      if (!ok) return false;
      skip_space();
      if (p_ >= end_) return false;
      if (*p_ == close) return ++p_, true;
      if (*p_ != ',') return false;
      ++p_;
    }
  }

  const char* p_;
  const char* end_;
  const std::string& label_;
  std::vector<std::string> path_;
  std::vector<bool> is_index_;
};

}  // namespace

void check_schema_ranges(const char* json, size_t size, const std::string& label) {
  Scanner(json, size, label).run();
}

}  // namespace tandem::gltf
