#include "app/render_frames.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "core/util/errors.h"

namespace tandem {

namespace {

constexpr uint32_t kMaxFrame = 1u << 24;

uint32_t parse_frame_number(const std::string& text, const std::string& option,
                            const std::string& whole) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || text[0] == '-' || text[0] == '+' || v < 0 ||
      v > kMaxFrame) {
    throw UsageError("render: " + option + " expects frame numbers 0.." +
                     std::to_string(kMaxFrame) + ", got '" + whole + "'");
  }
  return uint32_t(v);
}

}  // namespace

std::optional<RenderFrames> parse_render_frames(const std::optional<std::string>& frame,
                                                const std::optional<std::string>& frames,
                                                const std::optional<std::string>& fps,
                                                const std::string& output) {
  if (frame && frames) throw UsageError("render: give either --frame or --frames, not both");
  if (!frame && !frames) {
    if (fps) throw UsageError("render: --fps needs --frame or --frames");
    return std::nullopt;
  }
  RenderFrames r;
  if (frame) {
    r.first = r.last = parse_frame_number(*frame, "--frame", *frame);
  } else {
    const size_t dots = frames->find("..");
    if (dots == std::string::npos)
      throw UsageError("render: --frames expects a range A..B, got '" + *frames + "'");
    r.first = parse_frame_number(frames->substr(0, dots), "--frames", *frames);
    r.last = parse_frame_number(frames->substr(dots + 2), "--frames", *frames);
    if (r.last < r.first)
      throw UsageError("render: --frames range '" + *frames + "' ends before it starts");
  }
  if (fps) {
    char* end = nullptr;
    const double v = std::strtod(fps->c_str(), &end);
    if (fps->empty() || *end != '\0' || !std::isfinite(v) || v <= 0.0 || v > 1e6)
      throw UsageError("render: --fps expects a frame rate > 0, got '" + *fps + "'");
    r.fps = v;
  }
  if (r.count() > 1 && output.find('#') == std::string::npos) {
    throw UsageError("render: --frames renders " + std::to_string(r.count()) +
                     " frames; --output needs a frame-number pattern such as out_####.png, got '" +
                     output + "'");
  }
  return r;
}

std::string frame_output_name(const std::string& output, uint32_t frame) {
  const size_t end = output.find_last_of('#');
  if (end == std::string::npos) return output;
  size_t begin = end;
  while (begin > 0 && output[begin - 1] == '#')
    --begin;
  std::string number = std::to_string(frame);
  const size_t width = end - begin + 1;
  if (number.size() < width) number.insert(0, width - number.size(), '0');
  return output.substr(0, begin) + number + output.substr(end + 1);
}

}  // namespace tandem
