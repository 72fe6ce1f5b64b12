# Renders a glTF model with Blender Cycles as a reference for what
# `tandem render MODEL.gltf` draws without --env or a camera of its own:
# the model lit by Tandem's built-in sky (data/env/sky.hdr) and seen by the
# camera Tandem frames from the scene's bounds.
#
#   blender -b --factory-startup --python tools/compare/cycles_gltf.py -- \
#       --gltf MODEL.gltf --sky data/env/sky.hdr --spp 256 --max-depth 16 \
#       --width 256 --height 256 --threads 2 --output cycles.exr
#
# The model comes in through Blender's own glTF importer, which maps each
# glTF metallic-roughness material onto a Principled BSDF (base colour
# texture in sRGB, roughness and metallic from the G and B channels of the
# metallic-roughness texture, a tangent-space normal map, alpha for BLEND and
# MASK). The script then pins the Principled inputs that glTF leaves out to
# what Tandem's BSDF does: single-scattering GGX, no subsurface, sheen or
# clear coat, F0 = 0.04 for dielectrics. The occlusion texture the importer
# keeps aside is not used by either renderer. Render settings are those of
# cycles_common.py (unbiased path tracing, box filter, no denoising).
#
# With --gltf-camera the file's own camera is used, with --sky none the world
# is black, and the file's punctual lights (KHR_lights_punctual, whose
# intensity Tandem reads as radiometric: W/sr) become Cycles lights of the
# same intensity: a Cycles point or spot light of power P watts has
# intensity P / (4 pi) W/sr (measured: 100 W at 1 m over a white diffuse
# plane gives radiance 2.533 = 100 / (4 pi) / pi), so P = 4 pi I. Cycles'
# spot falls off by a smoothstep over the blend band (and the cosine to its
# axis), Tandem's by t^2 over [cos outer, cos inner]: the band is matched,
# not the shape. A material that is not double-sided emits from its front
# only in Tandem; Cycles emits from both sides, so its emission is masked
# on back faces (Cycles still samples them: its cost, not Tandem's).
#
# Prints `CYCLES_RENDER_SECONDS <s>` like cycles_cornell.py.
import argparse
import math
import os
import sys

import bpy
import mathutils

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cycles_common import configure_render, render_and_save, run_main  # noqa: E402
from cycles_cornell import to_blender  # noqa: E402

# Tandem's default vertical field of view for a scene without a camera
# (frame_bounds_camera's caller in app/cmd_render.cpp), in radians.
TANDEM_YFOV = 0.6911112


def from_blender(p):
    """Inverse of to_blender: Blender's Z-up frame -> the glTF Y-up frame."""
    x, y, z = p
    return (x, z, -y)


def world_bounds_gltf_frame():
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        mw = obj.matrix_world
        for v in obj.data.vertices:
            p = from_blender(mw @ v.co)
            for i in range(3):
                lo[i] = min(lo[i], p[i])
                hi[i] = max(hi[i], p[i])
    if lo[0] > hi[0]:
        raise RuntimeError("the glTF file has no mesh")
    return mathutils.Vector(lo), mathutils.Vector(hi)


def add_bounds_camera(aspect):
    """The camera of Tandem's frame_bounds_camera, built in the glTF frame
    and moved into Blender's: from the front (+z), slightly above, the
    bounding sphere filling the narrower field of view with a 5% margin."""
    lo, hi = world_bounds_gltf_frame()
    center = (lo + hi) * 0.5
    radius = max(0.5 * (hi - lo).length, 1e-3)
    fwd = mathutils.Vector((0.0, -0.25, -1.0)).normalized()
    half_fov = 0.5 * min(TANDEM_YFOV, 2.0 * math.atan(math.tan(0.5 * TANDEM_YFOV) * aspect))
    distance = radius / math.sin(half_fov) * 1.05
    position = center - fwd * distance
    right = fwd.cross(mathutils.Vector((0.0, 1.0, 0.0))).normalized()
    up = right.cross(fwd)

    scene = bpy.context.scene
    cam_data = bpy.data.cameras.new("tandem_bounds_camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.sensor_height = 24.0
    cam_data.sensor_width = 24.0 * aspect
    cam_data.lens = 12.0 / math.tan(0.5 * TANDEM_YFOV)
    cam_data.shift_x = cam_data.shift_y = 0.0
    cam_data.clip_start = 1e-4 * distance
    cam_data.clip_end = 1e3 * distance
    cam_data.dof.use_dof = False
    cam = bpy.data.objects.new("tandem_bounds_camera", cam_data)
    scene.collection.objects.link(cam)
    # A Blender camera looks down its local -Z with local +Y up and +X right.
    cols = [mathutils.Vector(to_blender(v)) for v in (right, up, -fwd)]
    rot = mathutils.Matrix((cols[0], cols[1], cols[2])).transposed()
    cam.matrix_world = mathutils.Matrix.Translation(to_blender(position)) @ rot.to_4x4()
    scene.camera = cam
    return position, fwd, distance


def add_sky_world(sky_path):
    """Tandem's equirectangular lookup puts u = 0.5 at -z (glTF frame) and
    u = 0.75 at +x; Cycles' puts u = 0.5 at +x (Blender frame), u = 0.25 at
    +y = glTF -z. Rotating the lookup direction by -90 degrees about
    Blender's z lines the two up; v runs from the top (+y glTF, +z Blender)
    in both. Bilinear filtering like Tandem's env_radiance."""
    world = bpy.data.worlds.new("tandem_sky")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes.get("Background")
    bg.inputs["Strength"].default_value = 1.0
    tex = nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(os.path.abspath(sky_path))
    tex.image.colorspace_settings.name = "Linear"
    tex.projection = "EQUIRECTANGULAR"
    tex.interpolation = "Linear"
    coord = nodes.new("ShaderNodeTexCoord")
    mapping = nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-90.0))
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bg.inputs["Color"])
    world.cycles.sampling_method = "AUTOMATIC"  # importance-sampled, like Tandem's env_sample
    bpy.context.scene.world = world


def use_file_camera(gltf_path, aspect):
    """The file's first camera, with Tandem's reading of its field of view
    (yfov vertical, whatever the image's aspect)."""
    import json
    with open(gltf_path, encoding="utf-8") as f:
        doc = json.load(f)
    cams = [o for o in bpy.context.scene.objects if o.type == "CAMERA"]
    if not cams or not doc.get("cameras"):
        raise RuntimeError("--gltf-camera: the file has no camera")
    cam = cams[0]
    yfov = doc["cameras"][0]["perspective"]["yfov"]
    cam.data.sensor_fit = "VERTICAL"
    cam.data.sensor_height = 24.0
    cam.data.sensor_width = 24.0 * aspect
    cam.data.lens = 12.0 / math.tan(0.5 * yfov)
    cam.data.shift_x = cam.data.shift_y = 0.0
    cam.data.dof.use_dof = False
    bpy.context.scene.camera = cam
    return cam


def set_punctual_lights(gltf_path):
    """Each KHR_lights_punctual light at Tandem's radiometric intensity."""
    import json
    with open(gltf_path, encoding="utf-8") as f:
        doc = json.load(f)
    lights = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    by_name = {l.get("name"): l for l in lights}
    count = 0
    for light in bpy.data.lights:
        src = by_name.get(light.name)
        if src is None:
            continue
        color = src.get("color", [1.0, 1.0, 1.0])
        light.color = color
        intensity = src.get("intensity", 1.0)
        if light.type == "SUN":
            light.energy = intensity  # W/m^2
            light.angle = 0.0
        else:
            light.energy = 4.0 * math.pi * intensity
            light.shadow_soft_size = 0.0
        if light.type == "SPOT":
            spot = src.get("spot", {})
            outer = spot.get("outerConeAngle", math.pi / 4)
            inner = spot.get("innerConeAngle", 0.0)
            light.spot_size = 2.0 * outer
            light.spot_blend = (math.cos(inner) - math.cos(outer)) / max(1.0 - math.cos(outer), 1e-6)
        light.cycles.max_bounces = 1024
        count += 1
    return count


def emit_from_front_only(gltf_path):
    """Masks the emission of single-sided glTF materials on back faces."""
    import json
    with open(gltf_path, encoding="utf-8") as f:
        doc = json.load(f)
    double = {m.get("name"): m.get("doubleSided", False) for m in doc.get("materials", [])}
    masked = 0
    for mat in bpy.data.materials:
        if not mat.use_nodes or double.get(mat.name, True):
            continue
        tree = mat.node_tree
        for node in tree.nodes:
            if node.type != "BSDF_PRINCIPLED":
                continue
            strength = node.inputs["Emission Strength"]
            if strength.is_linked or strength.default_value == 0.0:
                continue
            color = node.inputs["Emission"]
            if not color.is_linked and max(color.default_value[:3]) == 0.0:
                continue
            geometry = tree.nodes.new("ShaderNodeNewGeometry")
            front = tree.nodes.new("ShaderNodeMath")
            front.operation = "MULTIPLY_ADD"  # strength * (-backfacing) + strength
            front.inputs[1].default_value = -strength.default_value
            front.inputs[2].default_value = strength.default_value
            tree.links.new(geometry.outputs["Backfacing"], front.inputs[0])
            tree.links.new(front.outputs[0], strength)
            masked += 1
    return masked


def pin_principled_to_tandem():
    """Sets the Principled inputs glTF has no value for to Tandem's BSDF."""
    pinned = {
        "Subsurface": 0.0,
        "Specular": 0.5,  # F0 = 0.08 * specular = 0.04, glTF's dielectric F0
        "Specular Tint": 0.0,
        "Anisotropic": 0.0,
        "Sheen": 0.0,
        "Clearcoat": 0.0,
        "Transmission": 0.0,
        "IOR": 1.5,
    }
    count = 0
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        for node in mat.node_tree.nodes:
            if node.type != "BSDF_PRINCIPLED":
                continue
            node.distribution = "GGX"
            node.subsurface_method = "BURLEY"
            for name, value in pinned.items():
                sock = node.inputs.get(name)
                if sock is not None and not sock.is_linked:
                    sock.default_value = value
            count += 1
        # Stochastic transparency in Tandem: a hit is opaque with
        # probability alpha. Cycles' alpha is a transparent-BSDF mix, the
        # same in expectation.
        if mat.blend_method in ("BLEND", "HASHED"):
            mat.blend_method = "HASHED"
    return count


# Principled inputs a glTF texture can feed, and the glTF factor (with its
# default) that stands alone when the texture is missing.
FACTOR_OF_INPUT = {
    "Base Color": ("baseColorFactor", [1.0, 1.0, 1.0, 1.0]),
    "Alpha": ("baseColorFactor", [1.0, 1.0, 1.0, 1.0]),
    "Metallic": ("metallicFactor", 1.0),
    "Roughness": ("roughnessFactor", 1.0),
}


def drop_missing_textures(gltf_path):
    """Tandem ignores a texture whose image file cannot be read (with a
    warning) and renders the material from its factors alone. Blender would
    render such a texture magenta; unlink it from the Principled BSDF and set
    the input to the factor instead, so both render the same material."""
    import json
    with open(gltf_path, encoding="utf-8") as f:
        doc = json.load(f)
    factors = {m.get("name"): m.get("pbrMetallicRoughness", {}) for m in doc.get("materials", [])}
    dropped = []
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        tree = mat.node_tree
        for tex in [n for n in tree.nodes if n.type == "TEX_IMAGE"]:
            img = tex.image
            if img is not None and os.path.isfile(bpy.path.abspath(img.filepath)):
                continue
            # Every Principled input this image reaches, through any chain of nodes.
            reached, todo, seen = [], [tex], set()
            while todo:
                node = todo.pop()
                if node.name in seen:
                    continue
                seen.add(node.name)
                for out in node.outputs:
                    for link in out.links:
                        if link.to_node.type == "BSDF_PRINCIPLED":
                            reached.append((link.to_node, link.to_socket))
                        else:
                            todo.append(link.to_node)
            pbr = factors.get(mat.name, {})
            for bsdf, sock in reached:
                for link in list(sock.links):
                    tree.links.remove(link)
                if sock.name in FACTOR_OF_INPUT:
                    key, default = FACTOR_OF_INPUT[sock.name]
                    value = pbr.get(key, default)
                    sock.default_value = value if sock.name != "Alpha" else value[3]
                # Normal: unlinked means the shading normal, as in Tandem.
            dropped.append(f"{mat.name}:{img.name if img else '?'}")
            tree.nodes.remove(tex)
    return dropped


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="cycles_gltf.py", description="Cycles reference render of a glTF model")
    p.add_argument("--gltf", required=True, help="the .gltf or .glb file")
    p.add_argument("--sky", required=True, help="Tandem's built-in sky (data/env/sky.hdr), or none")
    p.add_argument("--gltf-camera", action="store_true", help="the file's camera, not one framing the bounds")
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--max-depth", type=int, default=16, help="Tandem's convention: 1 = direct light only")
    p.add_argument("--width", type=int, default=256)
    p.add_argument("--height", type=int, default=256)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--output", required=True, help="output .exr path")
    args = p.parse_args(argv)
    if args.max_depth < 1:
        p.error("--max-depth must be >= 1")
    if min(args.spp, args.width, args.height, args.threads) < 1:
        p.error("--spp, --width, --height and --threads must be >= 1")
    for path in (args.gltf, args.sky):
        if path != "none" and not os.path.isfile(path):
            p.error(f"{path}: no such file")
    return args


def import_gltf(path):
    # Blender's importer needs numpy (Debian: python3-numpy). Blender 3.4's
    # importer still uses np.bool, an alias numpy 1.24 removed.
    try:
        import numpy
    except ImportError:
        raise RuntimeError("Blender's glTF importer needs numpy (apt-get install python3-numpy)")
    if "bool" not in numpy.__dict__:
        numpy.bool = bool
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(path))


def main():
    args = parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    import_gltf(args.gltf)
    dropped = drop_missing_textures(args.gltf)
    if dropped:
        print(f"CYCLES_MISSING_TEXTURES {' '.join(dropped)}", flush=True)
    pinned = pin_principled_to_tandem()
    lights = set_punctual_lights(args.gltf)
    masked = emit_from_front_only(args.gltf)
    if args.gltf_camera:
        cam = use_file_camera(args.gltf, args.width / args.height)
        where = f"camera=file ({cam.name})"
    else:
        position, fwd, distance = add_bounds_camera(args.width / args.height)
        where = f"camera=({position.x:.4f},{position.y:.4f},{position.z:.4f}) distance={distance:.4f}"
    if args.sky == "none":
        world = bpy.data.worlds.new("black")
        world.use_nodes = True
        world.node_tree.nodes.get("Background").inputs["Strength"].default_value = 0.0
        bpy.context.scene.world = world
    else:
        add_sky_world(args.sky)
    configure_render(args)
    render_and_save(args, f"materials={pinned} lights={lights} front-only emitters={masked} {where}")


if __name__ == "__main__":
    run_main(main)
