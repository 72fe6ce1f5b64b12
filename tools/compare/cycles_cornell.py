# Renders the Cornell box with Blender Cycles as an independent reference for
# Tandem's builtin:cornell scene.
#
#   blender -b --factory-startup --python tools/compare/cycles_cornell.py -- \
#       --spp 1024 --max-depth 8 --width 256 --height 256 --threads 2 --output cycles.exr
#
# The geometry is transcribed here directly from the published measurement
# table of the Cornell box (https://www.graphics.cornell.edu/online/box/data.html,
# millimetres), not from Tandem's sources, so a transcription error on either
# side shows up as a disagreement instead of being shared.
#
# Settings are chosen so that Cycles computes the same estimand as Tandem:
# unbiased path tracing (no clamping, no light threshold, no denoising, no
# adaptive sampling, no path guiding, caustics on), a 1-pixel box filter
# (Tandem jitters uniformly inside each pixel), pure Lambertian BSDFs and a
# black world. The output is a linear, uncompressed 32-bit float EXR that
# Tandem's own reader accepts.
#
# Prints `CYCLES_RENDER_SECONDS <s>`: wall time of bpy.ops.render.render only
# (scene sync + BVH build + sampling), not Blender start-up or the EXR write.
import argparse
import math
import os
import sys

import bpy
import mathutils

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cycles_common import configure_render, render_and_save, run_main  # noqa: E402

# --- Published Cornell box data (mm). Each quad lists its vertices in the ---
# --- order of the table; the light's quad sits in the ceiling plane.     ---
FLOOR = [(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2)]
LIGHT = [(343.0, 548.8, 227.0), (343.0, 548.8, 332.0), (213.0, 548.8, 332.0), (213.0, 548.8, 227.0)]
CEILING = [(556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2), (0.0, 548.8, 0.0)]
BACK_WALL = [(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2)]
RIGHT_WALL = [(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2)]  # green
LEFT_WALL = [(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0)]  # red
SHORT_BLOCK = [
    [(130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0), (290.0, 165.0, 114.0)],
    [(290.0, 0.0, 114.0), (290.0, 165.0, 114.0), (240.0, 165.0, 272.0), (240.0, 0.0, 272.0)],
    [(130.0, 0.0, 65.0), (130.0, 165.0, 65.0), (290.0, 165.0, 114.0), (290.0, 0.0, 114.0)],
    [(82.0, 0.0, 225.0), (82.0, 165.0, 225.0), (130.0, 165.0, 65.0), (130.0, 0.0, 65.0)],
    [(240.0, 0.0, 272.0), (240.0, 165.0, 272.0), (82.0, 165.0, 225.0), (82.0, 0.0, 225.0)],
]
TALL_BLOCK = [
    [(423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0), (472.0, 330.0, 406.0)],
    [(423.0, 0.0, 247.0), (423.0, 330.0, 247.0), (472.0, 330.0, 406.0), (472.0, 0.0, 406.0)],
    [(472.0, 0.0, 406.0), (472.0, 330.0, 406.0), (314.0, 330.0, 456.0), (314.0, 0.0, 456.0)],
    [(314.0, 0.0, 456.0), (314.0, 330.0, 456.0), (265.0, 330.0, 296.0), (265.0, 0.0, 296.0)],
    [(265.0, 0.0, 296.0), (265.0, 330.0, 296.0), (423.0, 330.0, 247.0), (423.0, 0.0, 247.0)],
]
CAMERA_POSITION = (278.0, 273.0, -800.0)
CAMERA_DIRECTION = (0.0, 0.0, 1.0)
CAMERA_UP = (0.0, 1.0, 0.0)
FOCAL_LENGTH_MM = 35.0
FILM_SIZE_MM = 25.0  # square film: vertical FOV = 2 atan(12.5 / 35)

WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
LIGHT_RADIANCE = (17.0, 12.0, 4.0)

MM_TO_M = 0.001


def to_blender(p, scale=1.0):
    """Y-up data frame -> Blender's Z-up frame: (x, y, z) -> (x, -z, y).

    A proper rotation (+90 degrees about x, determinant +1), so handedness
    and hence left/right in the image are preserved."""
    x, y, z = p
    return (x * scale, -z * scale, y * scale)


def quad_triangles(q):
    # The published quads are not all planar (the red wall bows by a few mm);
    # split every quad along its v0-v2 diagonal so the surface is well defined.
    return [(q[0], q[1], q[2]), (q[0], q[2], q[3])]


def ceiling_with_hole():
    """The ceiling minus the light's rectangle, as four trapezoids between the
    outer and inner rectangles. The light lies in the ceiling plane, so with an
    intact ceiling the two surfaces would overlap (z-fighting)."""
    outer = CEILING
    # Pair each outer corner with the nearest light corner (same x/z side).
    def nearest(p):
        return min(LIGHT, key=lambda q: (q[0] - p[0]) ** 2 + (q[2] - p[2]) ** 2)

    inner = [nearest(p) for p in outer]
    quads = []
    for i in range(4):
        j = (i + 1) % 4
        quads.append([outer[i], outer[j], inner[j], inner[i]])
    return quads


def signed_normal(tri):
    a, b, c = (mathutils.Vector(v) for v in tri)
    return (b - a).cross(c - a)


def add_mesh(name, triangles, material, facing=None):
    """triangles in data coordinates (mm). `facing` (data frame) orients the
    winding; it only matters for the light (Cycles' BSDFs are two-sided)."""
    verts, faces = [], []
    for tri in triangles:
        if facing is not None and signed_normal(tri).dot(mathutils.Vector(facing)) < 0.0:
            tri = (tri[0], tri[2], tri[1])
        base = len(verts)
        verts.extend(to_blender(v, MM_TO_M) for v in tri)
        faces.append((base, base + 1, base + 2))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    mesh.update()
    for poly in mesh.polygons:
        poly.use_smooth = False
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


# --- The "spheres" variant: Tandem's builtin:cornell-spheres. The spheres ---
# --- are tessellated exactly as Tandem's make_uv_sphere (flat shaded), so ---
# --- both renderers see the same triangles.                              ---
SPHERE_RINGS = 24
SPHERE_RADIUS = 100.0
MIRROR_CENTER = (185.0, 100.0, 351.0)
GLASS_CENTER = (370.0, 100.0, 169.0)


def uv_sphere_triangles(center, radius, rings=SPHERE_RINGS):
    segments = 2 * rings
    verts = []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2.0 * math.pi * s / segments
            verts.append((center[0] + radius * math.sin(theta) * math.cos(phi),
                          center[1] + radius * math.cos(theta),
                          center[2] + radius * math.sin(theta) * math.sin(phi)))
    stride = segments + 1
    tris = []
    for r in range(rings):
        for s in range(segments):
            i0 = r * stride + s
            i1, i2 = i0 + 1, i0 + stride
            i3 = i2 + 1
            if r != 0:
                tris.append((verts[i0], verts[i1], verts[i2]))
            if r != rings - 1:
                tris.append((verts[i1], verts[i3], verts[i2]))
    return tris


def bsdf_material(name, node_type, inputs, distribution=None):
    """A material that is one BSDF node with the given input values."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    bsdf = nodes.new(node_type)
    if distribution is not None:
        bsdf.distribution = distribution
    for socket, value in inputs.items():
        bsdf.inputs[socket].default_value = value
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def mirror_material():
    # Tandem: metallic 1, roughness 0, base colour white -> Schlick F = 1: a
    # perfect mirror, which is Cycles' sharp white Glossy BSDF.
    return bsdf_material("mirror", "ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0, 1.0)}, "SHARP")


def glass_material():
    # Tandem: transmission 1, roughness 0, IOR 1.5: smooth dielectric with the
    # exact Fresnel equations, which is Cycles' sharp white Glass BSDF.
    return bsdf_material("glass", "ShaderNodeBsdfGlass", {"Color": (1.0, 1.0, 1.0, 1.0), "IOR": 1.5},
                         "SHARP")


def diffuse_material(name, rgb):
    # Roughness 0 = Lambert (no Oren-Nayar).
    return bsdf_material(name, "ShaderNodeBsdfDiffuse", {"Color": (*rgb, 1.0), "Roughness": 0.0})


def emission_material(name, radiance):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    strength = max(radiance)
    em = nodes.new("ShaderNodeEmission")
    # Cycles mesh emission: colour * strength is the emitted radiance.
    em.inputs["Color"].default_value = (*(c / strength for c in radiance), 1.0)
    em.inputs["Strength"].default_value = strength
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(em.outputs["Emission"], out.inputs["Surface"])
    if hasattr(mat.cycles, "sample_as_light"):
        mat.cycles.sample_as_light = True  # next-event estimation + MIS, like Tandem
    return mat


def build_scene(args):
    scene = bpy.context.scene
    white = diffuse_material("white", WHITE)
    red = diffuse_material("red", RED)
    green = diffuse_material("green", GREEN)
    light = emission_material("light", LIGHT_RADIANCE)

    add_mesh("floor", quad_triangles(FLOOR), white)
    add_mesh("back_wall", quad_triangles(BACK_WALL), white)
    add_mesh("red_wall", quad_triangles(LEFT_WALL), red)
    add_mesh("green_wall", quad_triangles(RIGHT_WALL), green)
    add_mesh("ceiling", [t for q in ceiling_with_hole() for t in quad_triangles(q)], white)
    if args.variant == "cornell":
        add_mesh("short_block", [t for q in SHORT_BLOCK for t in quad_triangles(q)], white)
        add_mesh("tall_block", [t for q in TALL_BLOCK for t in quad_triangles(q)], white)
    else:
        add_mesh("mirror_sphere", uv_sphere_triangles(MIRROR_CENTER, SPHERE_RADIUS), mirror_material())
        add_mesh("glass_sphere", uv_sphere_triangles(GLASS_CENTER, SPHERE_RADIUS), glass_material())
    # Cycles mesh lights emit from both faces; Tandem's light only from its
    # front (downward) face. The back face looks up into empty space: every
    # surface of the scene lies at or below the ceiling plane and the camera
    # is below it too, so no path can ever reach the back face and the two
    # conventions give identical images. The winding is set downward anyway.
    add_mesh("light", quad_triangles(LIGHT), light, facing=(0.0, -1.0, 0.0))

    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.sensor_height = FILM_SIZE_MM
    cam_data.sensor_width = FILM_SIZE_MM
    cam_data.lens = FOCAL_LENGTH_MM
    cam_data.shift_x = cam_data.shift_y = 0.0
    cam_data.clip_start = 1e-4
    cam_data.clip_end = 1e3
    cam_data.dof.use_dof = False
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    # A Blender camera looks down its local -Z with local +Y up and +X right.
    fwd = mathutils.Vector(CAMERA_DIRECTION).normalized()
    up = mathutils.Vector(CAMERA_UP)
    right = fwd.cross(up).normalized()
    up = right.cross(fwd)
    cols = [mathutils.Vector(to_blender(v)) for v in (right, up, -fwd)]
    rot = mathutils.Matrix((cols[0], cols[1], cols[2])).transposed()
    cam.matrix_world = mathutils.Matrix.Translation(to_blender(CAMERA_POSITION, MM_TO_M)) @ rot.to_4x4()
    scene.camera = cam

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    scene.world = world


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="cycles_cornell.py", description="Cycles reference render of the Cornell box")
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--max-depth", type=int, default=8, help="Tandem's convention: 1 = direct light only")
    p.add_argument("--width", type=int, default=256)
    p.add_argument("--height", type=int, default=256)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--output", required=True, help="output .exr path")
    p.add_argument("--variant", choices=["cornell", "spheres"], default="cornell",
                   help="cornell: the classic box; spheres: no blocks, a mirror and a glass sphere "
                        "(Tandem's builtin:cornell-spheres)")
    args = p.parse_args(argv)
    if args.max_depth < 1:
        p.error("--max-depth must be >= 1 (Cycles cannot render emission-only paths)")
    if min(args.spp, args.width, args.height, args.threads) < 1:
        p.error("--spp, --width, --height and --threads must be >= 1")
    return args


def main():
    args = parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build_scene(args)
    configure_render(args)
    c = bpy.context.scene.cycles
    render_and_save(args, f"pattern={c.sampling_pattern} filter={c.pixel_filter_type}/{c.filter_width}")


if __name__ == "__main__":
    run_main(main)
