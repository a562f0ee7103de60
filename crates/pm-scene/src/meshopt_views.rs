//! EXT_meshopt_compression (gltfpack's `-c`): buffer views whose bytes are
//! meshoptimizer-encoded in another buffer, decoded into the view's own place,
//! a fallback buffer that has no data of its own, so that accessors read them
//! as any others. Decoding is meshoptimizer's own (the `meshopt` crate's
//! bindings): the vertex codec for ATTRIBUTES, the index codecs for TRIANGLES
//! and INDICES, then the view's filter (OCTAHEDRAL, QUATERNION, EXPONENTIAL).

/// The extension's name.
pub(crate) const EXTENSION: &str = "EXT_meshopt_compression";

/// True when buffer `b` is a fallback buffer with nothing to read (the
/// extension's `fallback`, and no URI or one that is not there): its bytes are
/// what the compressed views decode to.
pub(crate) fn is_fallback(b: &gltf::Buffer) -> bool {
    b.extension_value(EXTENSION).and_then(|e| e.get("fallback")).and_then(|f| f.as_bool()) == Some(true)
}

/// Decode every compressed buffer view of `doc` into `buffers`. Errors name the
/// view and what is wrong.
pub(crate) fn decode_views(doc: &gltf::Document, buffers: &mut [gltf::buffer::Data]) -> Result<(), String> {
    for view in doc.views() {
        let Some(ext) = view.extension_value(EXTENSION) else { continue };
        let err = |m: String| format!("buffer view {} ({EXTENSION}): {m}", view.index());
        let num = |k: &str| ext.get(k).and_then(|v| v.as_u64()).map(|v| v as usize);
        let (Some(src_buffer), Some(length), Some(stride), Some(count)) =
            (num("buffer"), num("byteLength"), num("byteStride"), num("count"))
        else {
            return Err(err("buffer, byteLength, byteStride or count missing".into()));
        };
        let offset = num("byteOffset").unwrap_or(0);
        let mode = ext.get("mode").and_then(|v| v.as_str()).unwrap_or("");
        let filter = ext.get("filter").and_then(|v| v.as_str()).unwrap_or("NONE");
        let src = buffers
            .get(src_buffer)
            .and_then(|b| b.0.get(offset..offset.saturating_add(length)))
            .ok_or_else(|| err(format!("its data ({length} bytes at {offset} in buffer {src_buffer}) is not there")))?
            .to_vec();
        let bytes = decode(&src, mode, filter, stride, count).map_err(err)?;
        let dst = buffers
            .get_mut(view.buffer().index())
            .and_then(|b| b.0.get_mut(view.offset()..view.offset() + bytes.len()))
            .ok_or_else(|| err(format!("{} decoded bytes do not fit the view", bytes.len())))?;
        dst.copy_from_slice(&bytes);
    }
    Ok(())
}

/// One view's `count` elements of `stride` bytes, decoded.
fn decode(src: &[u8], mode: &str, filter: &str, stride: usize, count: usize) -> Result<Vec<u8>, String> {
    let bad = |e: meshopt::Error| format!("the {mode} data does not decode ({e})");
    match mode {
        "ATTRIBUTES" => {
            if stride == 0 || !stride.is_multiple_of(4) || stride > 256 {
                return Err(format!("byteStride {stride} is not a multiple of 4 up to 256"));
            }
            macro_rules! words {
                ($($k:literal)*) => {
                    match stride / 4 {
                        $($k => attributes::<$k>(src, count, filter).map_err(bad)?,)*
                        _ => unreachable!(),
                    }
                };
            }
            let bytes = words!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
                33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62 63 64);
            filtered(bytes, filter, stride)
        }
        "TRIANGLES" | "INDICES" => {
            // Decoded as 32-bit values (the codecs' output does not depend on
            // the width), written at the view's width.
            let v = if mode == "INDICES" {
                meshopt::decode_index_sequence::<u32>(src, count).map_err(bad)?
            } else {
                meshopt::decode_index_buffer::<u32>(src, count).map_err(bad)?
            };
            match stride {
                2 => Ok(v.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect()),
                4 => Ok(v.iter().flat_map(|i| i.to_le_bytes()).collect()),
                _ => Err(format!("index byteStride {stride} is not 2 or 4")),
            }
        }
        _ => Err(format!("mode '{mode}' is not ATTRIBUTES, TRIANGLES or INDICES")),
    }
}

/// `count` vertices of `K` 32-bit words, decoded by the vertex codec, with the
/// EXPONENTIAL filter (which works on words) applied.
fn attributes<const K: usize>(src: &[u8], count: usize, filter: &str) -> Result<Vec<u8>, meshopt::Error> {
    /// A vertex of K words (arrays have `Default` only up to 32).
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    struct Words<const K: usize>([u32; K]);
    impl<const K: usize> Default for Words<K> {
        fn default() -> Self {
            Words([0; K])
        }
    }
    let decoded = meshopt::decode_vertex_buffer::<Words<K>>(src, count)?;
    let mut v: Vec<[u32; K]> = decoded.into_iter().map(|w| w.0).collect();
    if filter == "EXPONENTIAL" {
        meshopt::decode_filter_exp::<K>(&mut v);
    }
    Ok(v.iter().flatten().flat_map(|w| w.to_ne_bytes()).collect())
}

/// The OCTAHEDRAL and QUATERNION filters, on 8- or 16-bit components.
fn filtered(bytes: Vec<u8>, filter: &str, stride: usize) -> Result<Vec<u8>, String> {
    match (filter, stride) {
        ("NONE" | "EXPONENTIAL", _) => Ok(bytes),
        ("OCTAHEDRAL", 4) => {
            let mut v: Vec<[i8; 4]> =
                bytes.chunks_exact(4).map(|c| std::array::from_fn(|k| i8::from_ne_bytes([c[k]]))).collect();
            meshopt::decode_filter_oct(&mut v);
            Ok(v.iter().flatten().flat_map(|c| c.to_ne_bytes()).collect())
        }
        ("OCTAHEDRAL" | "QUATERNION", 8) => {
            let mut v: Vec<[i16; 4]> = bytes
                .chunks_exact(8)
                .map(|c| std::array::from_fn(|k| i16::from_ne_bytes([c[2 * k], c[2 * k + 1]])))
                .collect();
            if filter == "OCTAHEDRAL" {
                meshopt::decode_filter_oct(&mut v);
            } else {
                meshopt::decode_filter_quat(&mut v);
            }
            Ok(v.iter().flatten().flat_map(|c| c.to_ne_bytes()).collect())
        }
        _ => Err(format!("filter '{filter}' on byteStride {stride} is not one the extension defines")),
    }
}
