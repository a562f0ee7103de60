//! The Blender add-on (`blender/photon_map/`) from here: staged into a folder
//! Blender can load (its Python files and `blender_manifest.toml`, with
//! `schema.json`: pipeline.toml's parameters from their one definition,
//! [`pm_pipeline::schema`], and the folder of the programs it runs), zipped as a
//! Blender extension (`cargo xtask blender-addon`), and the Python with Blender
//! as a module (`bpy` from PyPI, in a virtual environment under `target/`) that
//! its tests run under (`cargo xtask blender-test`, the test suite).

use anyhow::{Context, Result, bail};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The `bpy` release the tests run under (Blender 4.5 LTS; wheels for Python 3.11).
pub const BPY_VERSION: &str = "4.5.4";

/// The add-on's version, from its manifest.
pub fn addon_version(root: &Path) -> Result<String> {
    let manifest = root.join("blender/photon_map/blender_manifest.toml");
    let text = std::fs::read_to_string(&manifest).with_context(|| format!("{}: cannot read", manifest.display()))?;
    let table: toml::Table = text.parse().with_context(|| format!("{}: not TOML", manifest.display()))?;
    table
        .get("version")
        .and_then(|v| v.as_str())
        .map(str::to_owned)
        .with_context(|| format!("{}: no version", manifest.display()))
}

/// Copy the add-on into `dest/photon_map/` with its `schema.json` (the renderer's
/// parameters, and `bins`: the folder of the programs it runs unless told
/// otherwise). Returns the staged folder.
pub fn stage_addon(root: &Path, bins: &Path, dest: &Path) -> Result<PathBuf> {
    let src = root.join("blender/photon_map");
    let out = dest.join("photon_map");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    for entry in std::fs::read_dir(&src).with_context(|| format!("{}: cannot read", src.display()))? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if name.ends_with(".py") || name == "blender_manifest.toml" {
            std::fs::copy(&path, out.join(name)).with_context(|| format!("{}: cannot copy", path.display()))?;
        }
    }
    let mut schema = pm_pipeline::schema();
    schema["bins"] = serde_json::Value::String(std::path::absolute(bins)?.display().to_string());
    pm_stage::write_json(&out.join("schema.json"), &schema)?;
    Ok(out)
}

/// Zip the staged add-on folder `staged` as a Blender extension (its files at the
/// zip's root, deflated), atomically.
pub fn zip_addon(staged: &Path, zip: &Path) -> Result<()> {
    let mut names: Vec<String> = std::fs::read_dir(staged)?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| !n.starts_with('.') && n != "__pycache__")
        .collect();
    names.sort();
    let files = names
        .into_iter()
        .map(|n| {
            let bytes = std::fs::read(staged.join(&n))?;
            Ok((n, bytes))
        })
        .collect::<Result<Vec<_>>>()?;
    let bytes = zip_bytes(&files)?;
    pm_format::write_atomically(zip, |f| f.write_all(&bytes))
        .with_context(|| format!("{}: cannot write", zip.display()))
}

/// A zip archive of `files` (name, contents), each deflated, no timestamps (the
/// same files give the same bytes): local headers, then the central directory.
fn zip_bytes(files: &[(String, Vec<u8>)]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, data) in files {
        let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
        enc.write_all(data)?;
        let packed = enc.finish()?;
        let crc = crc32fast::hash(data);
        let offset = u32::try_from(out.len())?;
        let (n, c, u) = (u16::try_from(name.len())?, u32::try_from(packed.len())?, u32::try_from(data.len())?);
        // Version 2.0, no flags, deflate, time 00:00, date 1980-01-01.
        let common = |v: &mut Vec<u8>| {
            for x in [20u16, 0, 8, 0, 0x21] {
                v.extend_from_slice(&x.to_le_bytes());
            }
            for x in [crc, c, u] {
                v.extend_from_slice(&x.to_le_bytes());
            }
            v.extend_from_slice(&n.to_le_bytes());
            v.extend_from_slice(&0u16.to_le_bytes());
        };
        out.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        common(&mut out);
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&packed);
        central.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
        central.extend_from_slice(&20u16.to_le_bytes());
        common(&mut central);
        // Comment length, disk, internal and external attributes, offset.
        for x in [0u16, 0, 0] {
            central.extend_from_slice(&x.to_le_bytes());
        }
        central.extend_from_slice(&(0o100644u32 << 16).to_le_bytes());
        central.extend_from_slice(&offset.to_le_bytes());
        central.extend_from_slice(name.as_bytes());
    }
    let (at, size, count) = (u32::try_from(out.len())?, u32::try_from(central.len())?, u16::try_from(files.len())?);
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    for x in [0u16, 0, count, count] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&size.to_le_bytes());
    out.extend_from_slice(&at.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    Ok(out)
}

/// The Python of `target/bpy` (a virtual environment with `bpy` [`BPY_VERSION`]),
/// made when missing: `python3.11 -m venv`, then `pip install bpy` from PyPI
/// (about 350 MB to download, 950 MB installed; a minute or two).
pub fn ensure_bpy(root: &Path) -> Result<PathBuf> {
    let venv = crate::bins::target_dir(root).join("bpy");
    let python = venv.join("bin/python");
    let has = |p: &Path| {
        Command::new(p)
            .args(["-c", &format!("import importlib.metadata as m; assert m.version('bpy') == '{BPY_VERSION}'")])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if has(&python) {
        return Ok(python);
    }
    let base = ["python3.11", "python3"]
        .into_iter()
        .find(|p| {
            Command::new(p)
                .args(["-c", "import sys; assert sys.version_info[:2] == (3, 11)"])
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .context("bpy needs Python 3.11 (python3.11 on the PATH) for its tests")?;
    eprintln!("installing bpy {BPY_VERSION} into {} (a minute or two)", venv.display());
    let status = Command::new(base).args(["-m", "venv", "--clear"]).arg(&venv).status()?;
    if !status.success() {
        bail!("{base} -m venv {}: failed", venv.display());
    }
    let status = Command::new(&python)
        .args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check", &format!("bpy=={BPY_VERSION}")])
        .status()?;
    if !status.success() || !has(&python) {
        bail!("pip install bpy=={BPY_VERSION} into {}: failed", venv.display());
    }
    Ok(python)
}

/// Run the add-on's tests (`tests/blender/test_addon.py`) under `python` with the
/// add-on staged for the programs in `bins`, in `work`; Ok when every one passed.
/// Their output is passed through.
pub fn run_tests(root: &Path, python: &Path, bins: &Path, work: &Path, only: Option<&str>) -> Result<()> {
    let staged = stage_addon(root, bins, &work.join("addon"))?;
    let mut cmd = Command::new(python);
    cmd.arg(root.join("tests/blender/test_addon.py"))
        .arg("--addon")
        .arg(staged.parent().expect("staged in a folder"))
        .arg("--work")
        .arg(work)
        .env("PHOTON_MAP_BIN", bins);
    if let Some(t) = only {
        cmd.args(["--only", t]);
    }
    let status = cmd.status().context("cannot start the add-on's tests")?;
    if !status.success() {
        bail!("the Blender add-on's tests failed ({status})");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The zip is what unzip reads: each file back with its bytes.
    #[test]
    fn the_zip_holds_the_files() {
        let dir = tempfile::tempdir().unwrap();
        let files = vec![("a.py".to_string(), b"print(1)\n".repeat(50)), ("b.toml".to_string(), b"x = 1\n".to_vec())];
        let zip = dir.path().join("t.zip");
        std::fs::write(&zip, zip_bytes(&files).unwrap()).unwrap();
        let py = "import zipfile,sys; z=zipfile.ZipFile(sys.argv[1]); assert z.testzip() is None; print(','.join(z.namelist())); sys.stdout.write(z.read('a.py').decode()[:9])";
        let o = Command::new("python3").args(["-c", py]).arg(&zip).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(String::from_utf8_lossy(&o.stdout), "a.py,b.toml\nprint(1)\n");
    }
}
