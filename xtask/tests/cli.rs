//! The `xtask` binary's own command line (its integration tests also make cargo
//! build the binary that job plans run for their assemble step).

use std::process::Command;

/// Bad input to `cargo xtask assemble` is one line naming the file, exit code 1,
/// and no output file.
#[test]
fn assemble_names_a_missing_region_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("image.exr");
    let missing = dir.path().join("tile-0.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["assemble", missing.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains(missing.to_str().unwrap()) && err.trim().lines().count() == 1, "{err}");
    assert!(!out.exists());
}

/// `cargo xtask run --emit SYSTEM DIR` names an unknown job system in one line
/// before building or writing anything.
#[test]
fn run_emit_refuses_an_unknown_job_system() {
    let dir = tempfile::tempdir().unwrap();
    let jobs = dir.path().join("jobs");
    let o = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["run", "--emit", "pbs", jobs.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--emit pbs: expected slurm or openjd") && err.trim().lines().count() == 1, "{err}");
    assert!(!jobs.exists());
}
