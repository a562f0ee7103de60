// The coated room's floor tile (tests/blender/coated_room.py's 4 x 4 texture) as
// KTX2 with Basis Universal data, ETC1S (BasisLZ) and UASTC (zstd), for
// blender_coated_ktx2*.gltf (KHR_texture_basisu). Made with the npm package
// ktx2-encoder 0.6.0 (Basis Universal's own encoder built to WebAssembly):
//
//     npm install ktx2-encoder@0.6.0 && node ktx2_tile.mjs
//
// The glTF files are blender_coated.gltf with the tile's texture reading the
// KTX2 image through KHR_texture_basisu (required, no PNG fallback).
import { encodeToKTX2 } from "ktx2-encoder";
import { writeFileSync } from "fs";
// The coated room's 4 x 4 tile: texels (i, j) with j counted from the bottom; yellow at j == 2, i in 2..3.
const YELLOW = [0.85, 0.65, 0.05], LILAC = [0.55, 0.45, 0.75];
// The PNG's bytes: coated_room.py writes the colours as 8-bit values unchanged.
const enc = (c) => Math.round(255 * c);
const w = 4, h = 4, data = new Uint8Array(w * h * 4);
for (let row = 0; row < h; row++) for (let i = 0; i < w; i++) {
  const j = h - 1 - row; // image rows from the top
  const c = (j == 2 && (i == 2 || i == 3)) ? YELLOW : LILAC;
  const k = 4 * (row * w + i);
  data[k] = enc(c[0]); data[k + 1] = enc(c[1]); data[k + 2] = enc(c[2]); data[k + 3] = 255;
}
const imageDecoder = async () => ({ data, width: w, height: h });
for (const [name, uastc] of [["tile_etc1s.ktx2", false], ["tile_uastc.ktx2", true]]) {
  const out = await encodeToKTX2(new Uint8Array(1), { isUASTC: uastc, generateMipmap: false, imageDecoder, isKTX2File: true, enableDebug: false, qualityLevel: 255, compressionLevel: 2, isSetKTX2SRGBTransferFunc: true });
  writeFileSync(name, out);
  console.log(name, out.length);
}
