// Tandem in a game's window: the loop to copy. An SDL window shows the
// denoised frame every frame while the "game" moves a box around a lamp on
// a textured floor under the built-in sky; Tandem renders on every core but
// one, which it leaves to the game.
//
//   embed_window [--width W] [--height H] [--backend auto|cpu|cuda|hetero]
//                [--frames N --screenshot FILE.png]
//
// Keys: left/right turn the camera, space pauses the box, Esc quits.
// --frames N stops after N frames, the box moving a fixed step per frame
// (so a run is repeatable), and --screenshot writes the last frame shown.
// Exit status: 0, 1 on a tandem::Error or SDL failure, 2 on bad usage.
#include <tandem/tandem.h>

#include <SDL.h>

#include "example_geometry.h"
#include "example_options.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using embed_example::cube;
using embed_example::Geometry;

// A 64x64 two-tone checkerboard, for the floor.
std::vector<uint8_t> checkerboard() {
  std::vector<uint8_t> px(64 * 64 * 4);
  for (uint32_t y = 0; y < 64; ++y)
    for (uint32_t x = 0; x < 64; ++x) {
      const bool dark = ((x / 8) + (y / 8)) % 2 != 0;
      uint8_t* p = &px[(y * 64 + x) * 4];
      p[0] = dark ? 70 : 220, p[1] = dark ? 75 : 215, p[2] = dark ? 90 : 200, p[3] = 255;
    }
  return px;
}

// The camera on a circle around the scene, `angle` radians from +z.
tandem::CameraDesc orbit_camera(float angle) {
  tandem::CameraDesc c;
  c.position[0] = 6.0f * std::sin(angle), c.position[1] = 3.0f;
  c.position[2] = 6.0f * std::cos(angle);
  c.target[1] = 0.5f;
  return c;
}

// Where the box is at time t (seconds): circling the lamp, turning.
tandem::Transform box_at(double t) {
  const float a = float(t) * 0.8f;
  return tandem::Transform::translation(2.0f * std::cos(a), 0.5f, 2.0f * std::sin(a)) *
         tandem::Transform::rotation(-a, 0.0f, 1.0f, 0.0f);
}

[[noreturn]] void usage(const std::string& problem) {
  std::fprintf(stderr, "embed_window: %s\n", problem.c_str());
  std::fprintf(stderr,
               "usage: embed_window [--width W] [--height H] [--backend auto|cpu|cuda|hetero] "
               "[--frames N --screenshot FILE.png]\n");
  std::exit(2);
}

uint32_t number(const char* text, const char* option) {
  char* end = nullptr;
  const unsigned long v = std::strtoul(text, &end, 10);
  if (!*text || *end || v > 100000) usage(std::string(option) + ": not a number: " + text);
  return uint32_t(v);
}

// SDL's resources, released in reverse order however main() ends.
struct Sdl {
  SDL_Window* window = nullptr;
  SDL_Renderer* renderer = nullptr;
  SDL_Texture* texture = nullptr;
  ~Sdl() {
    if (texture) SDL_DestroyTexture(texture);
    if (renderer) SDL_DestroyRenderer(renderer);
    if (window) SDL_DestroyWindow(window);
    SDL_Quit();
  }
};

}  // namespace

int main(int argc, char** argv) {
  tandem::set_warnings_to_stderr(true);  // a game would pass set_log_callback its logger
  tandem::RendererOptions options;
  options.width = 640;
  options.height = 360;
  options.samples_per_frame = 1;
  options.max_depth = 4;
  options.denoise = true;     // the frame shown is the denoised one
  options.reserve_cores = 1;  // one core stays the game's
  uint32_t frames = 0;        // 0: until the window is closed
  std::string screenshot;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage(a + " needs a value");
    const char* v = argv[++i];
    if (a == "--width") {
      options.width = number(v, "--width");
    } else if (a == "--height") {
      options.height = number(v, "--height");
    } else if (a == "--frames") {
      frames = number(v, "--frames");
    } else if (a == "--screenshot") {
      screenshot = v;
    } else if (a == "--backend") {
      if (!embed_example::parse_backend(v, &options.backend))
        usage("--backend: expected auto, cpu, cuda or hetero, not " + std::string(v));
    } else {
      usage("unknown option " + a);
    }
  }
  if (!screenshot.empty() && frames == 0) usage("--screenshot needs --frames");

  if (SDL_Init(SDL_INIT_VIDEO) != 0) {
    std::fprintf(stderr, "embed_window: SDL_Init: %s\n", SDL_GetError());
    return 1;
  }
  Sdl sdl;
  try {
    tandem::Renderer renderer(options);  // checks the options before a window opens
    sdl.window = SDL_CreateWindow("Tandem", SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED,
                                  int(options.width), int(options.height), 0);
    if (sdl.window) sdl.renderer = SDL_CreateRenderer(sdl.window, -1, 0);
    if (sdl.renderer) {
      sdl.texture =
          SDL_CreateTexture(sdl.renderer, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING,
                            int(options.width), int(options.height));
    }
    if (!sdl.texture) {
      std::fprintf(stderr, "embed_window: no window: %s\n", SDL_GetError());
      return 1;
    }

    // The scene: a textured floor, an orange box, a lamp above, the sky.
    const std::vector<uint8_t> board = checkerboard();
    tandem::TextureDesc texture;
    texture.width = texture.height = 64;
    texture.rgba8 = board.data();
    tandem::MaterialDesc floor_material;
    floor_material.base_color[0] = floor_material.base_color[1] = floor_material.base_color[2] = 1;
    floor_material.base_color_texture = renderer.add_texture(texture);
    tandem::MaterialDesc box_material;
    box_material.base_color[0] = 0.9f, box_material.base_color[1] = 0.35f;
    box_material.base_color[2] = 0.1f;
    box_material.roughness = 0.25f;
    box_material.clearcoat = 1.0f;
    tandem::MaterialDesc lamp_material;
    lamp_material.emission[0] = 12.0f, lamp_material.emission[1] = 10.0f;
    lamp_material.emission[2] = 7.0f;
    Geometry floor;
    const float corner[3] = {-6, 0, 6}, along_x[3] = {12, 0, 0}, along_z[3] = {0, 0, -12};
    floor.add_quad(corner, along_x, along_z, 6.0f);  // the texture repeats 6 times
    const Geometry box = cube(0.5f), lamp = cube(0.2f);
    renderer.add_instance(renderer.add_mesh(floor.data(), renderer.add_material(floor_material)),
                          tandem::Transform::identity());
    const tandem::InstanceId moving = renderer.add_instance(
        renderer.add_mesh(box.data(), renderer.add_material(box_material)), box_at(0.0));
    renderer.add_instance(renderer.add_mesh(lamp.data(), renderer.add_material(lamp_material)),
                          tandem::Transform::translation(0.0f, 1.6f, 0.0f));
    renderer.use_default_sky(0.6f);
    float camera_angle = 0.0f;
    renderer.set_camera(orbit_camera(camera_angle));

    std::vector<uint8_t> pixels(size_t(options.width) * options.height * 3);
    const Uint64 start = SDL_GetPerformanceCounter();
    const double ticks = double(SDL_GetPerformanceFrequency());
    double game_time = 0.0, last_title = 0.0;
    bool paused = false, running = true;
    for (uint32_t f = 0; running && (frames == 0 || f < frames); ++f) {
      // Tandem renders this frame on its threads...
      renderer.begin_frame();
      // ...while the game handles input and moves things for the next one.
      SDL_Event e;
      float turn = 0.0f;
      while (SDL_PollEvent(&e)) {
        if (e.type == SDL_QUIT) running = false;
        if (e.type != SDL_KEYDOWN) continue;
        if (e.key.keysym.sym == SDLK_ESCAPE) running = false;
        if (e.key.keysym.sym == SDLK_LEFT) turn -= 0.1f;
        if (e.key.keysym.sym == SDLK_RIGHT) turn += 0.1f;
        if (e.key.keysym.sym == SDLK_SPACE) paused = !paused;
      }
      const double now = double(SDL_GetPerformanceCounter() - start) / ticks;
      const double step = frames > 0 ? 1.0 / 30.0 : now - game_time;
      if (!paused) renderer.set_instance_transform(moving, box_at(game_time + step));
      game_time += step;
      if (turn != 0.0f) renderer.set_camera(orbit_camera(camera_angle += turn));
      const tandem::FrameInfo info = renderer.end_frame();

      // The denoised frame straight into SDL's texture memory.
      renderer.copy_image_srgb8(pixels.data(), pixels.size(), 0.0f, tandem::ToneCurve::kAces,
                                tandem::FrameImage::kDenoised);
      SDL_UpdateTexture(sdl.texture, nullptr, pixels.data(), int(options.width) * 3);
      SDL_RenderClear(sdl.renderer);
      SDL_RenderCopy(sdl.renderer, sdl.texture, nullptr, nullptr);
      SDL_RenderPresent(sdl.renderer);
      if (now - last_title > 0.5) {
        char title[160];
        std::snprintf(title, sizeof title,
                      "Tandem - %.1f ms/frame (render %.1f, denoise %.1f) - %s",
                      info.seconds * 1e3 + info.denoise_seconds * 1e3, info.render_seconds * 1e3,
                      info.denoise_seconds * 1e3, renderer.backend_names().c_str());
        SDL_SetWindowTitle(sdl.window, title);
        last_title = now;
      }
    }
    if (!screenshot.empty()) {
      renderer.write_image(screenshot, 0.0f, tandem::ToneCurve::kAces,
                           tandem::FrameImage::kDenoised);
      std::printf("wrote %s\n", screenshot.c_str());
    }
  } catch (const tandem::Error& e) {
    std::fprintf(stderr, "embed_window: %s\n", e.what());
    return 1;
  }
  return 0;
}
