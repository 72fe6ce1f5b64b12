# What the Cycles reference scripts (cycles_cornell.py, cycles_gltf.py)
# share: the render settings that make Cycles compute Tandem's estimand, the
# render-and-save tail with its CYCLES_* lines for run_cornell_comparison.sh,
# the EXR header fix-up for Tandem's reader, and the exit-status wrapper.
# Imported by both; not run on its own.
import os
import struct
import sys
import time

import bpy


def configure_render(args):
    scene = bpy.context.scene
    r, c = scene.render, scene.cycles
    r.engine = "CYCLES"
    c.device = "CPU"
    c.feature_set = "SUPPORTED"
    r.threads_mode = "FIXED"
    r.threads = args.threads
    r.resolution_x, r.resolution_y, r.resolution_percentage = args.width, args.height, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.film_transparent = False
    r.use_motion_blur = False
    c.samples = args.spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = args.seed
    c.use_animated_seed = False
    c.sample_offset = 0
    c.auto_scrambling_distance = False
    c.scrambling_distance = 1.0
    c.time_limit = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.use_fast_gi = False
    c.direct_light_sampling_type = "MULTIPLE_IMPORTANCE_SAMPLING"
    if hasattr(c, "use_guiding"):
        c.use_guiding = False  # path guiding learns online: not reproducible
    c.film_exposure = 1.0
    # Tandem's --max-depth D counts scattering events (D = 1: direct light
    # only); Cycles' max_bounces counts bounces after the first hit (0: direct
    # light only). Every per-type limit is at least the total one so that only
    # the total limit applies.
    bounces = max(args.max_depth - 1, 0)
    c.max_bounces = bounces
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.volume_bounces = bounces
    c.transparent_max_bounces = max(bounces, 8)
    c.min_light_bounces = 0
    c.min_transparent_bounces = 0
    # Irrelevant for float EXR output, but keep the pipeline a no-op.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    img = r.image_settings
    img.file_format = "OPEN_EXR"
    img.color_mode = "RGB"
    img.color_depth = "32"
    img.exr_codec = "NONE"
    img.use_preview = False
    # No metadata stamps: keeps the EXR header minimal (see strip_long_exr_attributes).
    for prop in dir(r):
        if prop.startswith("use_stamp"):
            setattr(r, prop, False)
    vl = scene.view_layers[0]
    vl.use_pass_combined = True


def strip_long_exr_attributes(path):
    """Rewrites a single-part scanline EXR without header attributes whose
    names are longer than 31 bytes, and clears the "long names" flag.

    Cycles always adds render statistics such as
    `cycles.ViewLayer.synchronization_time` to the header, which makes
    Blender set the long-names bit (0x400) of the version field; Tandem's
    minimal EXR reader refuses any file with that bit. The pixel data is
    untouched: only the header shrinks and the scanline offsets move with it."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version = struct.unpack_from("<II", data, 0)
    if magic != 20000630 or version & 0x1200:  # tiled or multi-part: not ours
        raise RuntimeError(f"{path}: unexpected EXR layout (version field {version:#x})")
    pos, kept, height, compression = 8, [], None, None
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end]
        if not name:
            pos = end + 1
            break
        type_end = data.index(b"\0", end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        value_start = type_end + 5
        if name == b"dataWindow":
            y0, y1 = struct.unpack_from("<i4xi", data, value_start + 4)
            height = y1 - y0 + 1
        if name == b"compression":
            compression = data[value_start]
        if len(name) <= 31 and type_end - end - 1 <= 31:
            kept.append(data[pos:value_start + size])
        pos = value_start + size
    if compression != 0 or height is None:
        raise RuntimeError(f"{path}: expected an uncompressed scanline EXR")
    header = struct.pack("<II", magic, version & ~0x400) + b"".join(kept) + b"\0"
    shift = pos - len(header)
    offsets = struct.unpack_from(f"<{height}Q", data, pos)  # one scanline per chunk
    table = struct.pack(f"<{height}Q", *(o - shift for o in offsets))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header + table + data[pos + 8 * height:])
    os.replace(tmp, path)


def render_and_save(args, settings_extra=""):
    """Renders the scene built so far, prints CYCLES_SETTINGS (with
    settings_extra appended), CYCLES_RENDER_SECONDS (the wall time of
    bpy.ops.render.render alone: scene sync, BVH build and sampling, not
    Blender's start-up or the EXR write) and CYCLES_OUTPUT, and writes
    args.output as an EXR Tandem's reader accepts."""
    c = bpy.context.scene.cycles
    extra = f" {settings_extra}" if settings_extra else ""
    print(f"CYCLES_SETTINGS {args.width}x{args.height} spp={c.samples} max_bounces={c.max_bounces} "
          f"threads={bpy.context.scene.render.threads} seed={c.seed}{extra} "
          f"blender={bpy.app.version_string}", flush=True)
    start = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    seconds = time.perf_counter() - start
    print(f"CYCLES_RENDER_SECONDS {seconds:.3f}", flush=True)
    result = bpy.data.images["Render Result"]
    output = bpy.path.abspath(args.output)
    result.save_render(filepath=output, scene=bpy.context.scene)
    strip_long_exr_attributes(output)
    print(f"CYCLES_OUTPUT {args.output}", flush=True)


def run_main(main):
    """Runs main() so that blender exits with its status: argparse's exit
    code, or 1 with the traceback for any other error (blender -b would
    otherwise exit 0 after a failing script)."""
    try:
        main()
    except SystemExit as e:
        sys.stdout.flush()
        os._exit(e.code if isinstance(e.code, int) else 2)
    except Exception:
        import traceback
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
