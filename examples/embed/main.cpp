// Embedding Tandem: a floor, a box and a ceiling lamp built through the
// public API, rendered with the Brigade frame loop while the box slides
// across the floor, then written as a PNG.
//
//   embed [--output FILE.png] [--width W] [--height H] [--frames N]
//         [--still-frames N] [--spp N] [--backend auto|cpu|cuda|hetero]
//
// --frames N renders N frames with the box moving 0.5 units along +x per
// frame (from x = -1), then --still-frames more frames with it at rest to
// refine the image. Exit status: 0, 1 on a tandem::Error, 2 on bad usage.
#include <tandem/tandem.h>

#include "example_geometry.h"
#include "example_options.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using embed_example::Geometry;

Geometry quad_facing(float y, float half, bool down) {
  Geometry g;
  const float c[3] = {-half, y, -half};
  const float x[3] = {2 * half, 0, 0}, z[3] = {0, 0, 2 * half};
  if (down)
    g.add_quad(c, x, z);  // x cross z = -y
  else
    g.add_quad(c, z, x);  // z cross x = +y
  return g;
}

[[noreturn]] void usage(const std::string& problem) {
  std::fprintf(stderr, "embed: %s\n", problem.c_str());
  std::fprintf(stderr,
               "usage: embed [--output FILE.png] [--width W] [--height H] [--frames N] "
               "[--still-frames N] [--spp N] [--backend auto|cpu|cuda|hetero]\n");
  std::exit(2);
}

uint32_t number(const char* text, const char* option) {
  char* end = nullptr;
  const unsigned long v = std::strtoul(text, &end, 10);
  if (!*text || *end || v > 100000) usage(std::string(option) + ": not a number: " + text);
  return uint32_t(v);
}

}  // namespace

int main(int argc, char** argv) {
  // The library says nothing unless asked; a command-line host shows its
  // warnings (a game would pass set_log_callback its own logger).
  tandem::set_warnings_to_stderr(true);
  std::string output = "embed.png";
  tandem::RendererOptions options;
  options.width = 320;
  options.height = 240;
  options.samples_per_frame = 4;
  options.max_depth = 4;
  uint32_t frames = 4, still_frames = 4;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage(a + " needs a value");
    const char* v = argv[++i];
    if (a == "--output") {
      output = v;
    } else if (a == "--width") {
      options.width = number(v, "--width");
    } else if (a == "--height") {
      options.height = number(v, "--height");
    } else if (a == "--frames") {
      frames = number(v, "--frames");
    } else if (a == "--still-frames") {
      still_frames = number(v, "--still-frames");
    } else if (a == "--spp") {
      options.samples_per_frame = number(v, "--spp");
    } else if (a == "--backend") {
      if (!embed_example::parse_backend(v, &options.backend))
        usage("--backend: expected auto, cpu, cuda or hetero, not " + std::string(v));
    } else {
      usage("unknown option " + a);
    }
  }
  if (frames == 0) usage("--frames must be at least 1");

  try {
    tandem::Renderer renderer(options);

    tandem::MaterialDesc floor_material;  // matt light grey
    tandem::MaterialDesc box_material;
    box_material.base_color[0] = 0.8f, box_material.base_color[1] = 0.3f,
    box_material.base_color[2] = 0.1f;
    box_material.roughness = 0.3f;
    tandem::MaterialDesc lamp_material;
    lamp_material.base_color[0] = lamp_material.base_color[1] = lamp_material.base_color[2] = 0;
    lamp_material.emission[0] = lamp_material.emission[1] = lamp_material.emission[2] = 8.0f;

    const Geometry floor = quad_facing(0.0f, 5.0f, false);
    const Geometry cube = embed_example::cube(0.5f);
    const Geometry lamp = quad_facing(3.0f, 0.75f, true);
    renderer.add_instance(renderer.add_mesh(floor.data(), renderer.add_material(floor_material)),
                          tandem::Transform::identity());
    const tandem::MeshId cube_mesh =
        renderer.add_mesh(cube.data(), renderer.add_material(box_material));
    renderer.add_instance(renderer.add_mesh(lamp.data(), renderer.add_material(lamp_material)),
                          tandem::Transform::identity());

    // Where the box stands in frame f, turning as it slides.
    auto box_at = [](uint32_t f) {
      return tandem::Transform::translation(-1.0f + 0.5f * float(f), 0.5f, 0.0f) *
             tandem::Transform::rotation(0.3f * float(f), 0.0f, 1.0f, 0.0f);
    };
    const tandem::InstanceId moving = renderer.add_instance(cube_mesh, box_at(0));

    tandem::LightDesc fill;  // a dim point light so the box's sides are not black
    fill.position[0] = 3.0f, fill.position[1] = 2.0f, fill.position[2] = 3.0f;
    fill.intensity = 4.0f;
    renderer.add_light(fill);
    renderer.set_environment_color(0.05f, 0.06f, 0.08f);

    tandem::CameraDesc camera;
    camera.position[0] = 0.0f, camera.position[1] = 2.0f, camera.position[2] = 5.5f;
    camera.target[0] = 0.0f, camera.target[1] = 0.5f, camera.target[2] = 0.0f;
    renderer.set_camera(camera);

    // The Brigade loop: while frame f renders, the "game" moves the box to
    // where it stands in frame f + 1; on a GPU-only backend the next frame's
    // scene compile and BVH refit also overlap this frame's render.
    for (uint32_t f = 0; f < frames + still_frames; ++f) {
      renderer.begin_frame();
      if (f + 1 < frames) renderer.set_instance_transform(moving, box_at(f + 1));
      renderer.prepare_next_frame();
      const tandem::FrameInfo info = renderer.end_frame();
      std::printf("frame %u: %u spp, %.1f ms, %.2f Mrays\n", unsigned(f),
                  unsigned(info.accumulated_spp), info.seconds * 1e3, double(info.rays) * 1e-6);
    }
    renderer.write_image(output);
    std::printf("wrote %s (%ux%u, backends %s)\n", output.c_str(), unsigned(renderer.width()),
                unsigned(renderer.height()), renderer.backend_names().c_str());
  } catch (const tandem::Error& e) {
    std::fprintf(stderr, "embed: %s\n", e.what());
    return 1;
  }
  return 0;
}
