#include "app/render_frames.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <utility>

#include "core/image/image.h"
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
  } else if (*frames == "all") {
    r.whole_animation = true;
  } else {
    const size_t dots = frames->find("..");
    if (dots == std::string::npos)
      throw UsageError("render: --frames expects a range A..B, A..B..STEP or all, got '" + *frames +
                       "'");
    r.first = parse_frame_number(frames->substr(0, dots), "--frames", *frames);
    std::string rest = frames->substr(dots + 2);
    const size_t step_dots = rest.find("..");
    if (step_dots != std::string::npos) {
      r.step = parse_frame_number(rest.substr(step_dots + 2), "--frames", *frames);
      if (r.step == 0)
        throw UsageError("render: --frames step must be 1 or more, got '" + *frames + "'");
      rest = rest.substr(0, step_dots);
    }
    r.last = parse_frame_number(rest, "--frames", *frames);
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
  if ((r.count() > 1 || r.whole_animation) && output.find('#') == std::string::npos) {
    const std::string what =
        r.whole_animation ? "every frame of the animation" : std::to_string(r.count()) + " frames";
    throw UsageError("render: --frames renders " + what +
                     "; --output needs a frame-number pattern such as out_####.png, got '" +
                     output + "'");
  }
  return r;
}

uint32_t last_frame_within(double duration, double fps) {
  // The small tolerance keeps a duration of exactly k / fps at frame k.
  const double last = duration > 0.0 ? std::floor(duration * fps + 1e-6) : 0.0;
  return uint32_t(std::min<double>(last, kMaxFrame));
}

void resolve_whole_animation(RenderFrames& frames, double duration) {
  frames.first = 0;
  frames.last = last_frame_within(duration, frames.fps);
}

std::string frames_past_end_notice(const RenderFrames& frames, double duration) {
  if (duration <= 0.0) return "";
  const uint32_t last_within = last_frame_within(duration, frames.fps);
  const uint32_t final_frame = frames.final_frame();
  if (final_frame <= last_within) return "";
  // The first frame of the range past the end.
  const uint32_t first_past =
      frames.first > last_within
          ? frames.first
          : frames.first + ((last_within - frames.first) / frames.step + 1) * frames.step;
  char text[256];
  std::snprintf(text, sizeof text,
                "frames %u..%u are past the end of the animation (%.4g s long: its last frame at "
                "%g fps is %u); it loops, so they show it again from its start",
                first_past, final_frame, duration, frames.fps, last_within);
  return text;
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

void check_render_outputs(const std::string& output, const std::optional<RenderFrames>& frames,
                          const std::vector<std::string>& inputs) {
  // Inputs by file identity: a different spelling (./a.exr, a link) is the
  // same file.
  std::set<std::pair<dev_t, ino_t>> input_files, input_folders;
  const auto folder_of = [](const std::string& path) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    return parent.empty() ? std::string(".") : parent.string();
  };
  for (const std::string& input : inputs) {
    struct stat st = {}, folder = {};
    if (::stat(input.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;
    input_files.insert({st.st_dev, st.st_ino});
    if (::stat(folder_of(input).c_str(), &folder) == 0)
      input_folders.insert({folder.st_dev, folder.st_ino});
  }
  // Whether a folder holds an input (then each output in it is compared).
  const auto holds_input = [&](const std::string& folder) {
    struct stat st = {};
    return ::stat(folder.c_str(), &st) == 0 && input_folders.count({st.st_dev, st.st_ino}) > 0;
  };
  const auto check_not_input = [&](const std::string& path) {
    struct stat st = {};
    if (input_files.empty() || ::stat(path.c_str(), &st) != 0) return;
    if (input_files.count({st.st_dev, st.st_ino}) == 0) return;
    for (const std::string& input : inputs) {
      struct stat in = {};
      if (::stat(input.c_str(), &in) == 0 && in.st_dev == st.st_dev && in.st_ino == st.st_ino)
        throw InputError(path + ": is an input of this render (" + input +
                         "); writing the image there would destroy it");
    }
  };
  const RenderFrames range = frames.value_or(RenderFrames{});
  const bool pattern = frames.has_value() && output.find('#') != std::string::npos;
  if (!pattern) {
    check_output_path(output);
    check_not_input(output);
    return;
  }
  // The folder (and so what check_output_path asks of it) changes only
  // where the pattern is in a folder name; the name's length only where the
  // frame number outgrows the pattern.
  std::string last_folder;
  size_t last_length = 0;
  bool compare = false;
  for (uint32_t f = range.first;; f += range.step) {
    const std::string path = frame_output_name(output, f);
    std::string folder = folder_of(path);
    if (f == range.first || folder != last_folder || path.size() != last_length) {
      check_output_path(path);
      if (f == range.first || folder != last_folder) compare = holds_input(folder);
      last_folder = std::move(folder);
      last_length = path.size();
    }
    if (compare) check_not_input(path);
    if (f == range.final_frame()) break;
  }
}

}  // namespace tandem
