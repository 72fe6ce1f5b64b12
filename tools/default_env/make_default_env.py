#!/usr/bin/env python3
"""Writes Tandem's default environment: a soft daylight sky over a grey-brown
ground with a small sun, as an equirectangular Radiance .hdr (flat RGBE
scanlines, no dependencies).

    python3 tools/default_env/make_default_env.py data/env/sky.hdr

The map uses Tandem's equirectangular convention (core/kernel/sampling.h):
row 0 looks straight up (+y), and the column u of a direction d satisfies
u = atan2(d.x, -d.z) / 2pi + 0.5, so the middle column looks along -z.
Radiance is about 1 near the horizon: a glTF model under it renders at a
sensible brightness with exposure 0, and metals have a horizon, a ground and
a highlight to reflect.
"""
import math
import struct
import sys

WIDTH, HEIGHT = 256, 128

# Towards the sun: 40 degrees up, from behind and to the left of a camera on
# +z looking at the origin (the automatic camera's side).
SUN_ELEVATION = math.radians(40.0)
SUN_AZIMUTH = math.radians(35.0)  # from +z towards -x
SUN = (-math.cos(SUN_ELEVATION) * math.sin(SUN_AZIMUTH), math.sin(SUN_ELEVATION),
       math.cos(SUN_ELEVATION) * math.cos(SUN_AZIMUTH))
# The disc fades out over a few texels (1.4 degrees each): the renderer looks
# the map up bilinearly but samples it texel by texel, and a hard edge next
# to the dim sky is where the two disagree most (fireflies).
SUN_CORE = math.radians(2.5)
SUN_EDGE = math.radians(6.5)
SUN_RADIANCE = (80.0, 76.0, 67.0)

ZENITH = (0.50, 0.64, 0.95)
HORIZON = (1.05, 1.02, 0.95)
GROUND_NEAR = (0.45, 0.42, 0.38)
GROUND_FAR = (0.22, 0.20, 0.18)


def lerp(a, b, t):
    return tuple(x + (y - x) * t for x, y in zip(a, b))


def radiance(d):
    x, y, z = d
    if y >= 0.0:
        # Bright haze at the horizon, deeper blue overhead.
        c = lerp(HORIZON, ZENITH, math.pow(y, 0.6))
    else:
        # A short blend below the horizon, then ground getting darker below.
        haze = max(0.0, 1.0 + y / 0.06)
        c = lerp(lerp(GROUND_NEAR, GROUND_FAR, min(1.0, -y)), HORIZON, haze * haze * 0.8)
    cos_sun = max(-1.0, min(1.0, x * SUN[0] + y * SUN[1] + z * SUN[2]))
    angle = math.acos(cos_sun)
    glow = 1.5 * math.exp(-angle / 0.12)  # a soft halo around the disc
    c = tuple(v + glow for v in c)
    if angle < SUN_EDGE:
        t = min(1.0, (SUN_EDGE - angle) / (SUN_EDGE - SUN_CORE))
        fade = t * t * (3.0 - 2.0 * t)
        c = tuple(v + (s - v) * fade for v, s in zip(c, SUN_RADIANCE))
    return c


def rgbe(c):
    m = max(c)
    if m < 1e-32:
        return bytes((0, 0, 0, 0))
    mantissa, exponent = math.frexp(m)
    scale = mantissa * 256.0 / m
    return bytes([min(255, int(v * scale)) for v in c] + [exponent + 128])


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make_default_env.py OUTPUT.hdr")
    out = bytearray(b"#?RADIANCE\n# Tandem default sky (tools/default_env/make_default_env.py)\n"
                    b"FORMAT=32-bit_rle_rgbe\n\n")
    out += b"-Y %d +X %d\n" % (HEIGHT, WIDTH)
    for row in range(HEIGHT):
        theta = (row + 0.5) / HEIGHT * math.pi
        for col in range(WIDTH):
            phi = ((col + 0.5) / WIDTH - 0.5) * 2.0 * math.pi
            d = (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))
            out += rgbe(radiance(d))
    with open(sys.argv[1], "wb") as f:
        f.write(out)


if __name__ == "__main__":
    main()
