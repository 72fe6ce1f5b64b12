// `tandem render --frame N | --frames A..B[..S] | --frames all [--fps F]`:
// which animation frames to render and where each one goes, as Blender
// Cycles does it. Frame f is the scene at time f / fps; every S-th frame
// from A to B (S = 1 by default); `all` is frames 0 to the end of the
// longest animation. A run of '#' in the output name is replaced by the
// zero-padded frame number (out_####.png -> out_0001.png).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tandem {

struct RenderFrames {
  uint32_t first = 0, last = 0, step = 1;
  // `--frames all`: first and last come from the animation's length once
  // the scene is loaded (resolve_whole_animation); until then 0..0.
  bool whole_animation = false;
  double fps = 24.0;
  uint32_t count() const { return (last - first) / step + 1; }
  // The last frame rendered (last itself only when the step lands on it).
  uint32_t final_frame() const { return first + (count() - 1) * step; }
  uint32_t index(uint32_t frame) const { return (frame - first) / step; }
  double time(uint32_t frame) const { return double(frame) / fps; }
};

// The last frame whose time is within `duration` seconds at `fps` (0 for
// a scene that does not move).
uint32_t last_frame_within(double duration, double fps);

// For `--frames all`: frames 0 up to the last one within `duration`
// seconds (0..0 for a scene that does not move).
void resolve_whole_animation(RenderFrames& frames, double duration);

// The one line that says frames of `frames` lie past the end of an
// animation of `duration` seconds (it loops, so they repeat its start), or
// "" when none does or the scene does not move.
std::string frames_past_end_notice(const RenderFrames& frames, double duration);

// From the option values (each unset when not given): nullopt when neither
// --frame nor --frames is given (a still render of the scene as loaded).
// Throws UsageError for malformed values, both options at once, or several
// frames (or `all`) with an output name that has no '#' pattern.
std::optional<RenderFrames> parse_render_frames(const std::optional<std::string>& frame,
                                                const std::optional<std::string>& frames,
                                                const std::optional<std::string>& fps,
                                                const std::string& output);

// How many frames of the core tracer an offline render of `spp` samples
// per pixel takes: the tile split is rebalanced between frames and they
// drive the progress bar, but every frame also costs a hand-out and a
// barrier (on a distributed render a worker waits through both), so a frame
// carries at least 4 samples and a render has at most 32 frames.
inline uint32_t offline_frame_count(uint32_t spp) {
  const uint32_t frames = (spp + 3) / 4;
  return frames < 1 ? 1 : frames > 32 ? 32 : frames;
}

// `output` with its last run of '#' replaced by `frame`, zero-padded to the
// run's length (longer numbers are written in full); unchanged without '#'.
std::string frame_output_name(const std::string& output, uint32_t frame);

// Every output path of a render, checked before the scene is loaded: each
// frame's folder exists and is writable, its name with the temporary
// file's suffix fits (check_output_path), and none is one of `inputs` (the
// scene file, the environment map), which rendering would overwrite. A run
// of '#' in a folder name gives each frame a folder of its own: all are
// checked. Throws InputError naming the path.
void check_render_outputs(const std::string& output, const std::optional<RenderFrames>& frames,
                          const std::vector<std::string>& inputs);

}  // namespace tandem
