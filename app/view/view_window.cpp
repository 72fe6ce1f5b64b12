#include "app/view/view_window.h"

#include <SDL.h>
#include <SDL_opengl.h>
#include <imgui.h>
#include <imgui_impl_opengl2.h>
#include <imgui_impl_sdl.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <optional>

#include "app/view/camera_controller.h"
#include "app/view/image_filters.h"
#include "app/view/scripted_path.h"
#include "core/util/errors.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

const char* const kHelp =
    "Fly (default):  W/A/S/D move, Q/E down/up, Shift faster, left-drag look\n"
    "Orbit (Tab):    left-drag orbit, right-drag pan, wheel zoom\n"
    "P pause scene motion    F1 this help    F12 screenshot (PNG)    Esc quit\n"
    "Nothing moving: samples accumulate. Motion: resolution adapts to the target fps.";

struct UiState {
  bool show_help = false;
  bool orbit_mode = false;
  int backend = 0;  // index into kBackendNames
  int max_depth = 4;
  int max_spp = 16;
  float exposure = 0.0f, light_scale = 1.0f, aperture = 0.0f, focus = 1.0f, target_fps = 30.0f;
  bool denoise = true, split = false;
  double fps = 0.0;
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
  if (ImGui::Checkbox("denoise motion", &ui.denoise)) s.set_denoise(ui.denoise);
  ImGui::SameLine();
  ImGui::Checkbox("pause scene", &s.paused);
  if (ImGui::SliderInt("max spp/frame", &ui.max_spp, 1, 64))
    s.set_max_spp_per_frame(uint32_t(ui.max_spp));
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
  ImGui::Text("%.1f fps  %.1f ms/frame  %ux%u (scale %.2f)  %u spp/frame", ui.fps,
              m.total_seconds * 1e3, ts.render.width, ts.render.height, s.quality().scale,
              ts.samples_per_frame);
  ImGui::Text("accumulated: %u spp", s.tracer().accumulated_spp());
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

void run_headless_script(ViewSession& session, uint32_t frames, const std::string& screenshot) {
  const Camera base = session.camera();
  for (uint32_t f = 0; f < frames; ++f) {
    const double t = double(f) * kScriptedFrameStep;
    session.advance_scene(t);
    session.set_camera(scripted_camera(base, t));
    session.render(true);
  }
  if (!screenshot.empty()) session.screenshot(screenshot);
}

bool run_view_window(ViewSession& session, const WindowRunOptions& opt, std::string* error) {
  if (SDL_Init(SDL_INIT_VIDEO) != 0) {
    *error = std::string("cannot initialise SDL video: ") + SDL_GetError();
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
  ui.exposure = vo.exposure;
  ui.denoise = vo.denoise;
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
  double scene_time = 0.0;
  auto last = Clock::now();
  uint32_t frame = 0;
  bool running = true;
  while (running) {
    const auto now = Clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    CameraInput in;
    in.dt = dt;
    SDL_Event ev;
    ImGuiIO& io = ImGui::GetIO();
    while (SDL_PollEvent(&ev)) {
      ImGui_ImplSDL2_ProcessEvent(&ev);
      if (ev.type == SDL_QUIT) running = false;
      if (ev.type == SDL_WINDOWEVENT && ev.window.event == SDL_WINDOWEVENT_SIZE_CHANGED) {
        session.set_output_size(uint32_t(ev.window.data1), uint32_t(ev.window.data2));
      }
      if (ev.type == SDL_KEYDOWN && !io.WantCaptureKeyboard) {
        switch (ev.key.keysym.sym) {
          case SDLK_ESCAPE:
            running = false;
            break;
          case SDLK_F1:
            ui.show_help = !ui.show_help;
            break;
          case SDLK_TAB:
            ui.orbit_mode = !ui.orbit_mode;
            break;
          case SDLK_p:
            session.paused = !session.paused;
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
    }
    if (!io.WantCaptureKeyboard) {
      const Uint8* k = SDL_GetKeyboardState(nullptr);
      in.forward = k[SDL_SCANCODE_W], in.back = k[SDL_SCANCODE_S];
      in.left = k[SDL_SCANCODE_A], in.right = k[SDL_SCANCODE_D];
      in.up = k[SDL_SCANCODE_E], in.down = k[SDL_SCANCODE_Q];
      in.fast = k[SDL_SCANCODE_LSHIFT] || k[SDL_SCANCODE_RSHIFT];
    }

    bool moved = false;
    if (opt.scripted_frames > 0) {
      scene_time = double(frame) * kScriptedFrameStep;
      session.set_camera(scripted_camera(base, scene_time));
      moved = true;
    } else {
      // Switching controllers continues from the current view.
      if (ui.orbit_mode != was_orbit) {
        if (ui.orbit_mode)
          orbit = OrbitCamera(camera, camera_target(camera));
        else
          fly = FlyCamera(camera, fly_speed(session));
        was_orbit = ui.orbit_mode;
      }
      camera = session.camera();
      moved = ui.orbit_mode ? orbit.update(in, camera) : fly.update(in, camera);
      if (moved) session.set_camera(camera);
      if (!session.paused) scene_time += std::min(dt, 0.1);  // no jumps after a stall
    }
    moved |= session.advance_scene(scene_time);
    const FrameMetrics& m = session.render(moved);
    ui.fps = ui.fps == 0.0 ? 1.0 / std::max(dt, 1e-6) : 0.9 * ui.fps + 0.1 / std::max(dt, 1e-6);

    glBindTexture(GL_TEXTURE_2D, texture);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, GLsizei(session.display_width()),
                 GLsizei(session.display_height()), 0, GL_RGB, GL_UNSIGNED_BYTE,
                 session.display().data());
    ImGui_ImplOpenGL2_NewFrame();
    ImGui_ImplSDL2_NewFrame();
    ImGui::NewFrame();
    ImGui::GetBackgroundDrawList()->AddImage(reinterpret_cast<ImTextureID>(uintptr_t(texture)),
                                             ImVec2(0, 0), io.DisplaySize);
    draw_panel(session, ui, m);
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

    ++frame;
    if (opt.scripted_frames > 0 && frame >= opt.scripted_frames) {
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
