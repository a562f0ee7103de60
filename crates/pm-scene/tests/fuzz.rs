//! Fuzzing the glTF-to-scene conversion: mutated copies of a hand-written glTF (text
//! edits and byte flips) and of a .glb must load or fail with a one-line error
//! naming the file, never panic. Inputs that ever crashed the loader are kept in
//! tests/corpus/ and replayed here; a new crash is saved under the build's
//! temporary folder (never into the source tree) for a developer to move there.

use proptest::prelude::*;
use std::path::PathBuf;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests").join(name)
}

fn check(bytes: &[u8], ext: &str) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(format!("fuzz.{ext}"));
    std::fs::write(&p, bytes).unwrap();
    let result = std::panic::catch_unwind(|| pm_scene::load(&p).map(|s| s.triangles.len()));
    match result {
        Err(_) => {
            // Save the crashing input for a developer to keep in tests/corpus/.
            let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-crashes");
            std::fs::create_dir_all(&dir).unwrap();
            let keep = dir.join(format!("crash-{}.{ext}", blake3::hash(bytes).to_hex()));
            std::fs::write(&keep, bytes).unwrap();
            Err(TestCaseError::fail(format!(
                "loader panicked; input saved to {} (move it to crates/pm-scene/tests/corpus/ to replay it)",
                keep.display()
            )))
        }
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => {
            let msg = e.to_string();
            prop_assert!(msg.contains("fuzz.") && !msg.contains('\n'), "{}", msg);
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Numbers in the JSON replaced by extreme or wrong values, keys dropped.
    #[test]
    fn mutated_gltf_text(edits in proptest::collection::vec((0usize..4000, 0u8..8), 1..6)) {
        let mut text = std::fs::read_to_string(data("data/handmade.gltf")).unwrap();
        for (at, kind) in edits {
            let at = at % text.len();
            let Some(start) = text[at..].find(|c: char| c.is_ascii_digit()).map(|i| i + at) else { continue };
            let end = text[start..].find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-')).map_or(text.len(), |i| i + start);
            let repl = ["-1", "1e39", "NaN", "99999999", "0", "3.5", "\"x\"", "[]"][kind as usize];
            text.replace_range(start..end, repl);
        }
        check(text.as_bytes(), "gltf")?;
    }

    /// Raw byte flips and truncation of a binary glTF.
    #[test]
    fn mutated_glb_bytes(flips in proptest::collection::vec((0usize..3000, any::<u8>()), 0..8), cut in proptest::option::of(0usize..3000)) {
        let mut bytes = std::fs::read(data("data/handmade_gltf_transform.glb")).unwrap();
        for (at, v) in flips {
            let n = bytes.len();
            bytes[at % n] ^= v;
        }
        if let Some(c) = cut {
            bytes.truncate(c.min(bytes.len()));
        }
        check(&bytes, "glb")?;
    }
}

#[test]
fn corpus_of_past_crashes_loads_without_panic() {
    for entry in std::fs::read_dir(data("corpus")).unwrap() {
        let p = entry.unwrap().path();
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("gltf").to_owned();
        if ext == "gltf" || ext == "glb" {
            check(&std::fs::read(&p).unwrap(), &ext).unwrap();
        }
    }
}
