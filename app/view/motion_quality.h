// The quality of what the viewer shows while things move: the image shown
// (denoised, at the reduced resolution the frame rate allowed, resampled to
// the window) against a converged reference of the same frame, as relMSE.
// Measured beside the frame rate so that the resolution floor and the work
// per frame are chosen from both, not from speed alone.
#pragma once

#include <cstdint>

#include "app/view/view_session.h"
#include "core/world/scene.h"

namespace tandem {

// relMSE (app/render_denoise.h) of session.shown_linear(), bilinearly
// resampled to the output size, against `frame` (the Scene as that frame
// rendered it, camera included) rendered at the output size with
// `reference_spp` samples per pixel on the CPU.
double motion_relmse(const Scene& frame, const ViewSession& session, uint32_t reference_spp);

// Whether frame f of a scripted run of `frames` is one of the four whose
// motion quality is measured (spread over the path, never the first, which
// builds the scene). None for runs of under 5 frames.
inline bool motion_quality_frame(uint32_t f, uint32_t frames) {
  return frames >= 5 && f > 0 && f % (frames / 5) == 0 && f / (frames / 5) <= 4;
}

}  // namespace tandem
