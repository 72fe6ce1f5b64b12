// The SDL2 + OpenGL 2 + Dear ImGui front end of tandem-view.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "app/view/input_waits.h"
#include "app/view/view_session.h"

namespace tandem {

struct WindowRunOptions {
  // > 0: headless script: N frames along the scripted camera path with the
  // scene at fixed time steps, then write `screenshot` and return.
  uint32_t scripted_frames = 0;
  // Then this many frames with the camera and the scene held still: a
  // still image refining (full resolution, more samples a frame).
  uint32_t still_frames = 0;
  std::string screenshot;  // also the F12 target when set
  bool hidden = false;     // do not show the window (scripted runs)
  // When set, receive the times between reads of the event queue and
  // between presented frames (seconds), from the first frame presented on
  // (the first builds the scene).
  InputWaits* input_waits = nullptr;
  std::vector<double>* frame_seconds = nullptr;
};

// Opens the window and runs until Esc / close (or the script ends). Returns
// false without side effects when no window can be created (no display),
// with the reason in `error`.
bool run_view_window(ViewSession& session, const WindowRunOptions& options, std::string* error);

// What a headless scripted run records, where set: what WindowRunOptions's
// fields of the same names receive (the points where a window would read
// its input and present), and with reference_spp > 0 the motion quality
// (motion_quality.h) of four frames spread over the path, their
// reference renders left out of the other figures. frame_seconds has the
// frames along the path only (the motion frame rate); the input waits
// cover the still frames too.
struct ScriptRecord {
  InputWaits* input_waits = nullptr;
  std::vector<double>* frame_seconds = nullptr;
  uint32_t reference_spp = 0;
  std::vector<double>* motion_relmse = nullptr;
};

// The same frames as a scripted window run, without any window (for
// machines with no display at all).
void run_headless_script(ViewSession& session, uint32_t frames, uint32_t still_frames,
                         const std::string& screenshot, const ScriptRecord& record = {});

}  // namespace tandem
