"""The two image files the add-on handles itself: it writes an environment image
as OpenEXR (scanlines, no compression, 32-bit float R, G, B: the plainest EXR,
which the renderer reads), and reads the renderer's layers back as Portable
Float Maps (`cargo xtask layers`: float RGB, the bottom row first, as Blender's
render passes are)."""

import os
import struct

import numpy as np


def _attr(name, kind, data):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def write_rgb(path, pixels):
    """Write `pixels` (height x width x 3, row 0 at the top; linear radiance) as
    an uncompressed scanline OpenEXR, atomically (a temporary file renamed)."""
    px = np.ascontiguousarray(pixels, dtype="<f4")
    h, w, _ = px.shape
    channels = b"".join(c + b"\0" + struct.pack("<iBBBBii", 2, 0, 0, 0, 0, 1, 1) for c in (b"B", b"G", b"R")) + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"".join([
        struct.pack("<ii", 20000630, 2),
        _attr("channels", "chlist", channels),
        _attr("compression", "compression", b"\0"),
        _attr("dataWindow", "box2i", box),
        _attr("displayWindow", "box2i", box),
        _attr("lineOrder", "lineOrder", b"\0"),
        _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        b"\0",
    ])
    line = 8 + 3 * 4 * w
    start = len(header) + 8 * h
    offsets = struct.pack(f"<{h}Q", *(start + y * line for y in range(h)))
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header)
        f.write(offsets)
        for y in range(h):
            f.write(struct.pack("<ii", y, 3 * 4 * w))
            for c in (2, 1, 0):
                f.write(px[y, :, c].tobytes())
    os.replace(tmp, path)


def read_pfm(path):
    """A Portable Float Map as an array of height x width x 3, the bottom row
    first (as written)."""
    with open(path, "rb") as f:
        data = f.read()
    parts = data.split(b"\n", 3)
    if len(parts) < 4 or parts[0] != b"PF":
        raise ValueError(f"{path}: not a colour Portable Float Map")
    w, h = (int(x) for x in parts[1].split())
    scale = float(parts[2])
    px = np.frombuffer(parts[3], dtype="<f4" if scale < 0 else ">f4", count=w * h * 3)
    return px.reshape(h, w, 3)
