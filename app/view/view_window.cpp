#include "app/view/view_window.h"

#include <SDL.h>
#include <SDL_opengl.h>
#include <imgui.h>
#include <imgui_impl_opengl2.h>
#include <imgui_impl_sdl.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <optional>

#include "app/view/camera_controller.h"
#include "app/view/frame_counter.h"
#include "app/view/image_filters.h"
#include "app/view/motion_quality.h"
#include "app/view/scripted_path.h"
#include "core/util/errors.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

const char* const kHelp =
    "Fly (default):  W/A/S/D move, Q/E down/up, Shift faster, left-drag look\n"
    "Orbit (Tab):    left-drag orbit, right-drag pan, wheel zoom\n"
    "Home/R reset the camera    C the file's next camera    P pause scene motion\n"
    "F1 this help    F12 screenshot (PNG)\n"
    "N denoiser (SVGF) on/off   B cycle the shown buffer (image, albedo, normal, depth,\n"
    "motion, variance, history length)\n"
    "Esc quit. Nothing moving: samples accumulate up to the target spp, then rendering stops.\n"
    "Motion: resolution adapts to the target fps.";

struct UiState {
  bool show_help = false;
  bool orbit_mode = false;
  int backend = 0;  // index into kBackendNames
  int max_depth = 4;
  int max_spp = 16;
  int target_spp = 1024;
  float exposure = 0.0f, light_scale = 1.0f, aperture = 0.0f, focus = 1.0f, target_fps = 30.0f;
  bool split = false;
  FrameCounter counter;
  std::string message;
};

const char* const kBackendNames[] = {"auto", "cpu", "cuda", "hetero"};
const BackendKind kBackendKinds[] = {BackendKind::kAuto, BackendKind::kCpu, BackendKind::kCuda,
                                     BackendKind::kHetero};

// Crossing the scene takes a few seconds whatever its units.
float fly_speed(ViewSession& s) {
  return std::max(0.25f * s.scene().bounds().radius(), 0.1f);
}

std::string default_screenshot_name() {
  char buf[64];
  const std::time_t now = std::time(nullptr);
  std::strftime(buf, sizeof buf, "tandem-view-%Y%m%d-%H%M%S.png", std::localtime(&now));
  return buf;
}

// The panel; returns nothing, applies changes to the session directly.
void draw_panel(ViewSession& s, UiState& ui, const FrameMetrics& m) {
  const bool converged = s.converged();
  ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.75f);
  ImGui::Begin("tandem-view", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  if (ImGui::Combo("backend", &ui.backend, kBackendNames, 4)) {
    try {
      s.set_backend(kBackendKinds[ui.backend]);
      ui.message.clear();
    } catch (const std::exception& e) {
      ui.message = e.what();  // e.g. cuda without a device: keep the old backends
    }
  }
  if (!ui.message.empty()) ImGui::TextWrapped("%s", ui.message.c_str());
  if (ImGui::Checkbox("split view", &ui.split)) s.set_split_view(ui.split);
  ImGui::SameLine();
  bool denoise = s.denoise();
  if (ImGui::Checkbox("denoise (SVGF)", &denoise)) s.set_denoise(denoise);
  ImGui::SameLine();
  ImGui::Checkbox("pause scene", &s.paused);
  if (ImGui::SliderInt("max spp/frame", &ui.max_spp, 1, 64))
    s.set_max_spp_per_frame(uint32_t(ui.max_spp));
  if (ImGui::SliderInt("target spp", &ui.target_spp, 1, 65536, "%d", ImGuiSliderFlags_Logarithmic))
    s.set_target_spp(uint32_t(ui.target_spp));
  if (ImGui::SliderInt("max depth", &ui.max_depth, 1, 16)) s.set_max_depth(uint32_t(ui.max_depth));
  if (ImGui::SliderFloat("exposure", &ui.exposure, -5.0f, 5.0f, "%.1f stops"))
    s.set_exposure(ui.exposure);
  if (ImGui::SliderFloat("light intensity", &ui.light_scale, 0.0f, 4.0f, "x%.2f"))
    s.set_light_scale(ui.light_scale);
  bool lens = ImGui::SliderFloat("aperture", &ui.aperture, 0.0f, 0.2f, "%.3f");
  lens |= ImGui::SliderFloat("focus distance", &ui.focus, 0.1f, 50.0f, "%.2f",
                             ImGuiSliderFlags_Logarithmic);
  if (lens) s.set_lens(ui.aperture, ui.focus);
  if (ImGui::SliderFloat("target fps", &ui.target_fps, 5.0f, 120.0f, "%.0f"))
    s.set_target_fps(ui.target_fps);
  if (ImGui::RadioButton("fly camera", !ui.orbit_mode)) ui.orbit_mode = false;
  ImGui::SameLine();
  if (ImGui::RadioButton("orbit camera", ui.orbit_mode)) ui.orbit_mode = true;
  ImGui::Separator();
  const TracerSettings& ts = s.tracer().settings();
  const double fps = ui.counter.fps(), ms = ui.counter.ms_per_rendered_frame();
  // Presented frames also pay for the display; rendering is the part the
  // resolution controls.
  char rendering[48] = "not rendering";
  if (ms > 0.0) std::snprintf(rendering, sizeof rendering, "%.1f ms rendering", ms);
  if (fps > 0.0)
    ImGui::Text("%.1f fps presented (%.1f ms apart)  %s", fps, 1e3 / fps, rendering);
  else
    ImGui::Text("-- fps presented  %s", rendering);
  ImGui::Text("%ux%u (scale %.2f)  %u spp/frame", ts.render.width, ts.render.height,
              s.quality().scale, ts.samples_per_frame);
  if (s.last_frame_moving()) {
    ImGui::Text("accumulated: %u spp (moving: every frame starts over)", s.accumulated_spp());
  } else if (converged) {
    ImGui::TextColored(ImVec4(0.4f, 1.0f, 0.4f, 1.0f),
                       "accumulated: %u / %u spp  converged (rendering stopped)",
                       s.accumulated_spp(), s.target_spp());
  } else {
    ImGui::Text("accumulated: %u / %u spp  converging", s.accumulated_spp(), s.target_spp());
  }
  int buffer = int(s.view_buffer());
  if (ImGui::Combo(
          "show", &buffer,
          [](void*, int i, const char** out) {
            *out = view_buffer_name(ViewBuffer(i));
            return true;
          },
          nullptr, int(ViewBuffer::kCount)))
    s.set_view_buffer(ViewBuffer(buffer));
  if (s.showing_denoised()) {
    ImGui::Text("denoiser: %.1f ms (features + SVGF), accumulated image weight %.0f%%",
                s.last_denoise_seconds() * 1e3, s.accumulated_weight() * 100.0);
  } else {
    ImGui::Text("denoiser: %s", !s.denoise() ? "off" : "idle (accumulated image shown)");
  }
  ImGui::Text("commit: %.1f KiB/frame (delta)", double(m.delta_bytes) / 1024.0);
  for (size_t i = 0; i < m.backends.size(); ++i) {
    const BackendFrameMetrics& b = m.backends[i];
    float c[3];
    backend_color(i, c);
    ImGui::TextColored(ImVec4(c[0], c[1], c[2], 1.0f),
                       "%-8s %6.1f Mrays/s  %3u tiles  share %4.0f%%  commit %.1f KiB",
                       b.name.c_str(), b.mrays_per_second(), b.tiles, b.planned_share * 100.0,
                       double(b.commit_bytes) / 1024.0);
  }
  ImGui::End();
}

}  // namespace

void run_headless_script(ViewSession& session, uint32_t frames, uint32_t still_frames,
                         const std::string& screenshot, const ScriptRecord& record) {
  InputWaits* input_waits = record.input_waits;
  std::vector<double>* frame_seconds = record.frame_seconds;
  const Camera base = session.camera();
  const auto start = Clock::now();
  // From the end of the first frame, which builds the scene (loading, not
  // a frame's work).
  bool measuring = false;
  auto polled = [&] {
    if (input_waits != nullptr && measuring)
      input_waits->polled(std::chrono::duration<double>(Clock::now() - start).count());
    return false;
  };
  session.advance_scene(0.0);
  for (uint32_t f = 0; f < frames; ++f) {
    measuring = f > 0;
    // Frame f + 1's scene is posed while frame f renders.
    session.set_camera(scripted_camera(base, double(f) * kScriptedFrameStep));
    // Four frames spread over the path (never the first) are measured, on
    // a copy of the scene as this frame renders it (a copy, like the
    // reference render, is no part of the loop: the input waits skip both).
    const bool measured = record.reference_spp > 0 && record.motion_relmse != nullptr &&
                          motion_quality_frame(f, frames);
    std::optional<Scene> frame_scene;
    if (measured) {
      frame_scene = session.scene();
      if (input_waits != nullptr) input_waits->pause();
    }
    polled();
    const auto frame_start = Clock::now();
    session.render_frame(true, double(f + 1) * kScriptedFrameStep, polled);
    if (frame_seconds != nullptr && f > 0) {
      session.display();  // what presenting it costs
      frame_seconds->push_back(std::chrono::duration<double>(Clock::now() - frame_start).count());
    }
    if (frame_scene) {
      record.motion_relmse->push_back(motion_relmse(*frame_scene, session, record.reference_spp));
      if (input_waits != nullptr) input_waits->pause();
    }
  }
  // The last pose held: the image refines as it would on screen.
  for (uint32_t f = 0; f < still_frames; ++f) {
    measuring = true;
    polled();
    session.render_frame(false, std::nullopt, polled);
  }
  polled();
  if (!screenshot.empty()) session.screenshot(screenshot);
}

bool run_view_window(ViewSession& session, const WindowRunOptions& opt, std::string* error) {
  const char* requested = SDL_getenv("SDL_VIDEODRIVER");
  if (SDL_Init(SDL_INIT_VIDEO) != 0) {
    *error = std::string("cannot initialise SDL video: ") + SDL_GetError();
    return false;
  }
  // Without a display SDL falls back to drivers that "open" windows nobody
  // can see (offscreen, dummy): the viewer would then render invisibly
  // forever. Only take them when asked for by name.
  const char* driver = SDL_GetCurrentVideoDriver();
  if (!(requested && *requested) && driver &&
      (std::strcmp(driver, "offscreen") == 0 || std::strcmp(driver, "dummy") == 0)) {
    *error = std::string(
                 "no display to open a window on (DISPLAY/WAYLAND_DISPLAY unset or "
                 "unusable; SDL found only its '") +
             driver + "' video driver); for a run without a window use --no-window --frames N";
    SDL_Quit();
    return false;
  }
  SDL_GL_SetAttribute(SDL_GL_DOUBLEBUFFER, 1);
  const Uint32 flags = SDL_WINDOW_OPENGL | SDL_WINDOW_RESIZABLE |
                       (opt.hidden ? SDL_WINDOW_HIDDEN : SDL_WINDOW_SHOWN);
  const ViewOptions& vo = session.options();
  SDL_Window* window =
      SDL_CreateWindow("tandem-view", SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, int(vo.width),
                       int(vo.height), flags);
  SDL_GLContext gl = window ? SDL_GL_CreateContext(window) : nullptr;
  if (!gl) {
    *error = std::string("cannot open an OpenGL window: ") + SDL_GetError();
    if (window) SDL_DestroyWindow(window);
    SDL_Quit();
    return false;
  }
  SDL_GL_MakeCurrent(window, gl);
  SDL_GL_SetSwapInterval(0);  // the path tracer sets the pace, not vsync
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to the user's files
  ImGui_ImplSDL2_InitForOpenGL(window, gl);
  ImGui_ImplOpenGL2_Init();
  GLuint texture = 0;
  glGenTextures(1, &texture);
  glBindTexture(GL_TEXTURE_2D, texture);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);

  UiState ui;
  ui.max_depth = int(vo.max_depth);
  ui.max_spp = int(vo.max_spp_per_frame);
  ui.target_spp = int(std::min(vo.target_spp, 65536u));
  ui.exposure = vo.exposure;
  ui.split = vo.split_view;
  ui.target_fps = float(vo.target_fps);
  ui.aperture = session.camera().aperture_radius;
  ui.focus = session.camera().focus_distance;
  for (int i = 0; i < 4; ++i)
    if (kBackendKinds[i] == vo.backend) ui.backend = i;

  const Camera base = session.camera();
  FlyCamera fly(base, fly_speed(session));
  OrbitCamera orbit(base, camera_target(base));
  bool was_orbit = false;
  Camera camera = base;
  session.advance_scene(0.0);
  double scene_time = 0.0;
  const auto start = Clock::now();
  auto seconds_now = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  double last = seconds_now();
  uint32_t frame = 0;
  bool running = true, idle = false;
  FrameMetrics metrics;  // of the last rendered frame
  double last_presented = seconds_now();
  InputWaits own_waits;
  InputWaits& waits = opt.input_waits != nullptr ? *opt.input_waits : own_waits;
  // Input read between frames and while one renders (ViewSession's
  // InputPoll), so no key waits for a frame to end.
  CameraInput in;
  bool reset_camera = false;
  ImGuiIO& io = ImGui::GetIO();
  // Whether an event changes what is seen (a still image being refined is
  // then cancelled at once) and whether it quits, without acting on it.
  auto changes_view = [&](const SDL_Event& ev) {
    switch (ev.type) {
      case SDL_WINDOWEVENT:
        return ev.window.event == SDL_WINDOWEVENT_SIZE_CHANGED;
      case SDL_KEYDOWN:
        return !io.WantCaptureKeyboard && ev.key.keysym.sym != SDLK_F1 &&
               ev.key.keysym.sym != SDLK_F12;
      case SDL_MOUSEMOTION:
        return !io.WantCaptureMouse && (ev.motion.state & (SDL_BUTTON_LMASK | SDL_BUTTON_RMASK));
      case SDL_MOUSEWHEEL:
        return !io.WantCaptureMouse && ui.orbit_mode;
      default:
        return false;
    }
  };
  auto quits = [&](const SDL_Event& ev) {
    return ev.type == SDL_QUIT ||
           (ev.type == SDL_KEYDOWN && !io.WantCaptureKeyboard && ev.key.keysym.sym == SDLK_ESCAPE);
  };
  // One event, acted on.
  auto handle = [&](const SDL_Event& ev) {
    ImGui_ImplSDL2_ProcessEvent(&ev);
    if (quits(ev)) running = false;
    if (ev.type == SDL_WINDOWEVENT && ev.window.event == SDL_WINDOWEVENT_SIZE_CHANGED)
      session.set_output_size(uint32_t(ev.window.data1), uint32_t(ev.window.data2));
    if (ev.type == SDL_KEYDOWN && !io.WantCaptureKeyboard) {
      switch (ev.key.keysym.sym) {
        case SDLK_F1:
          ui.show_help = !ui.show_help;
          break;
        case SDLK_TAB:
          ui.orbit_mode = !ui.orbit_mode;
          break;
        case SDLK_p:
          session.paused = !session.paused;
          break;
        case SDLK_n:
          session.set_denoise(!session.denoise());
          break;
        case SDLK_b:
          session.set_view_buffer(
              ViewBuffer((int(session.view_buffer()) + 1) % int(ViewBuffer::kCount)));
          break;
        case SDLK_HOME:
        case SDLK_r:
          reset_camera = true;
          break;
        case SDLK_c:
          // The file's next camera, then taken over like Home/R's.
          session.next_file_camera();
          reset_camera = true;
          break;
        case SDLK_F12: {
          const std::string path =
              opt.screenshot.empty() ? default_screenshot_name() : opt.screenshot;
          try {
            session.screenshot(path);
            ui.message = "saved " + path;
          } catch (const std::exception& e) {
            ui.message = e.what();
          }
          break;
        }
        default:
          break;
      }
    }
    if (ev.type == SDL_MOUSEMOTION && !io.WantCaptureMouse) {
      const glm::vec2 d(float(ev.motion.xrel), float(ev.motion.yrel));
      if (ev.motion.state & SDL_BUTTON_LMASK) (ui.orbit_mode ? in.orbit : in.look) += d;
      if ((ev.motion.state & SDL_BUTTON_RMASK) && ui.orbit_mode) in.pan += d;
    }
    if (ev.type == SDL_MOUSEWHEEL && !io.WantCaptureMouse && ui.orbit_mode)
      in.wheel += float(ev.wheel.y);
  };
  // Measured from the first frame presented (the first frame builds the
  // scene: loading, not a frame's work).
  bool measuring = false;
  // Events read while a frame renders or is filtered wait here: the
  // session is not changed under its own frame (ViewSession::render_frame).
  std::vector<SDL_Event> deferred;
  auto read_input = [&] {
    if (measuring) waits.polled(seconds_now());
    for (const SDL_Event& ev : deferred)
      handle(ev);
    deferred.clear();
    SDL_Event ev;
    while (SDL_PollEvent(&ev))
      handle(ev);
  };
  // Returns whether anything read changes what is seen.
  auto read_input_during_frame = [&] {
    if (measuring) waits.polled(seconds_now());
    bool changes = false;
    SDL_Event ev;
    while (SDL_PollEvent(&ev)) {
      if (quits(ev)) running = false;
      changes |= changes_view(ev);
      deferred.push_back(ev);
    }
    return changes;
  };
  while (running) {
    // A converged still image is not rendered again: sleep until input.
    if (idle && deferred.empty()) SDL_WaitEventTimeout(nullptr, 100);
    const double now = seconds_now();
    const double dt = now - last;
    last = now;
    in.dt = clamp_frame_delta(dt);
    read_input();
    if (!io.WantCaptureKeyboard) {
      const Uint8* k = SDL_GetKeyboardState(nullptr);
      in.forward = k[SDL_SCANCODE_W], in.back = k[SDL_SCANCODE_S];
      in.left = k[SDL_SCANCODE_A], in.right = k[SDL_SCANCODE_D];
      in.up = k[SDL_SCANCODE_E], in.down = k[SDL_SCANCODE_Q];
      in.fast = k[SDL_SCANCODE_LSHIFT] || k[SDL_SCANCODE_RSHIFT];
    }

    bool moved = false;
    std::optional<double> next_time;  // the next frame's scene time
    if (opt.scripted_frames > 0) {
      // Along the path, then held still.
      if (frame < opt.scripted_frames) {
        session.set_camera(scripted_camera(base, double(frame) * kScriptedFrameStep));
        next_time = double(frame + 1) * kScriptedFrameStep;
        moved = true;
      }
    } else {
      if (reset_camera) {
        session.reset_camera();
        camera = session.camera();
        fly = FlyCamera(camera, fly_speed(session));
        orbit = OrbitCamera(camera, camera_target(camera));
        moved = true;
      }
      // Switching controllers continues from the current view.
      if (ui.orbit_mode != was_orbit) {
        if (ui.orbit_mode)
          orbit = OrbitCamera(camera, camera_target(camera));
        else
          fly = FlyCamera(camera, fly_speed(session));
        was_orbit = ui.orbit_mode;
      }
      camera = session.camera();
      const bool stepped = ui.orbit_mode ? orbit.update(in, camera) : fly.update(in, camera);
      if (stepped) session.set_camera(camera);
      moved |= stepped;
      // The scene advances by real time, but no more than a frame's step
      // after a stall.
      if (!session.paused && session.has_motion()) {
        scene_time += clamp_frame_delta(dt);
        next_time = scene_time;
      }
    }
    // Nothing changes and the image has its samples: present it as it is.
    idle = !moved && !next_time && session.converged();
    in = CameraInput{};  // taken; what arrives while rendering is the next frame's
    reset_camera = false;
    double render_seconds = 0.0;
    if (!idle) {
      const double t0 = seconds_now();
      // A still image being refined gives way to any input that changes
      // the view, and anything gives way to a quit.
      const bool still = !moved && !next_time;
      const FrameMetrics& m = session.render_frame(moved, next_time, [&] {
        const bool changes = read_input_during_frame();
        return !running || (still && changes);
      });
      render_seconds = seconds_now() - t0;
      if (!m.cancelled) metrics = m;
    }
    // Tone mapping a full-resolution frame takes ~20 ms on two cores:
    // input is read again before it and before the upload and the present.
    read_input_during_frame();
    session.display();
    read_input_during_frame();

    glBindTexture(GL_TEXTURE_2D, texture);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, GLsizei(session.display_width()),
                 GLsizei(session.display_height()), 0, GL_RGB, GL_UNSIGNED_BYTE,
                 session.display().data());
    ImGui_ImplOpenGL2_NewFrame();
    ImGui_ImplSDL2_NewFrame();
    ImGui::NewFrame();
    ImGui::GetBackgroundDrawList()->AddImage(reinterpret_cast<ImTextureID>(uintptr_t(texture)),
                                             ImVec2(0, 0), io.DisplaySize);
    draw_panel(session, ui, metrics);
    if (ui.show_help) {
      ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x * 0.5f, io.DisplaySize.y - 8.0f),
                              ImGuiCond_Always, ImVec2(0.5f, 1.0f));
      ImGui::Begin("help", nullptr,
                   ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoTitleBar);
      ImGui::TextUnformatted(kHelp);
      ImGui::End();
    }
    ImGui::Render();
    glViewport(0, 0, int(io.DisplaySize.x), int(io.DisplaySize.y));
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    ImGui_ImplOpenGL2_RenderDrawData(ImGui::GetDrawData());
    SDL_GL_SwapWindow(window);
    const double presented = seconds_now();
    ui.counter.presented(presented, render_seconds);
    const bool still_phase = opt.scripted_frames > 0 && frame >= opt.scripted_frames;
    if (opt.frame_seconds != nullptr && !idle && measuring && !still_phase) {
      opt.frame_seconds->push_back(presented - last_presented);
    }
    last_presented = presented;
    measuring = true;

    ++frame;
    if (opt.scripted_frames > 0 && frame >= opt.scripted_frames + opt.still_frames) {
      if (!opt.screenshot.empty()) session.screenshot(opt.screenshot);
      running = false;
    }
  }
  glDeleteTextures(1, &texture);
  ImGui_ImplOpenGL2_Shutdown();
  ImGui_ImplSDL2_Shutdown();
  ImGui::DestroyContext();
  SDL_GL_DeleteContext(gl);
  SDL_DestroyWindow(window);
  SDL_Quit();
  return true;
}

}  // namespace tandem
