//! The stage binaries: where cargo puts them, building them, and running one so
//! that a failure's error keeps what the stage said.

use anyhow::{Context, Result, bail};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Every binary the README tells a user to run, built by [`Bins::build`].
pub const STAGES: [&str; 6] =
    ["photon-trace", "photon-sort", "photon-irradiance", "photon-render", "photon-inspect", "photon-live"];

/// The folder of the release stage binaries, and how long a stage may run.
#[derive(Clone, Debug)]
pub struct Bins {
    /// The folder.
    pub dir: PathBuf,
    /// The longest a stage run through [`run`] may take before it is killed and
    /// its step fails as timed out (none: no limit). The differential checks'
    /// guard against a hang.
    pub time_limit: Option<std::time::Duration>,
}

/// Cargo's target folder for the workspace at `root`: `$CARGO_TARGET_DIR` when
/// that is set (relative to the current folder, as cargo reads it), else
/// `root/target`.
pub fn target_dir(root: &Path) -> PathBuf {
    let cwd = std::env::current_dir().unwrap_or_default();
    target_dir_with(root, std::env::var_os("CARGO_TARGET_DIR"), &cwd)
}

/// [`target_dir`] with the variable's value and the current folder given.
fn target_dir_with(root: &Path, target_dir: Option<std::ffi::OsString>, cwd: &Path) -> PathBuf {
    match target_dir {
        Some(t) if !t.is_empty() => cwd.join(t),
        _ => root.join("target"),
    }
}

impl Bins {
    /// The binaries in `dir`, with no time limit.
    pub fn at(dir: PathBuf) -> Bins {
        Bins { dir, time_limit: None }
    }

    /// Where cargo puts release binaries of the workspace at `root`:
    /// `$CARGO_TARGET_DIR/release` when that is set (relative to the current
    /// folder, as cargo reads it), else `root/target/release`.
    pub fn locate(root: &Path) -> Bins {
        Bins::at(target_dir(root).join("release"))
    }

    /// Build every stage binary (release) and locate them.
    pub fn build(root: &Path) -> Result<Bins> {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(root).args(["build", "--release", "--quiet"]);
        for s in STAGES {
            cmd.args(["-p", s]);
        }
        let status = cmd.status().context("cannot run cargo build")?;
        if !status.success() {
            bail!("building the stage binaries failed");
        }
        Ok(Bins::locate(root))
    }

    /// The path of binary `name`.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
    }

    /// Fail, naming the first one, unless every stage binary is there.
    pub fn check(&self) -> Result<()> {
        for s in STAGES {
            if !self.path(s).exists() {
                bail!("{} is missing: build the stages (cargo build --release)", self.path(s).display());
            }
        }
        Ok(())
    }
}

/// Run stage `program` with `args` as step `step`. Its stderr is passed through
/// (unless `quiet`) and kept: when the stage fails, the error names the step and
/// ends with the stage's own last message.
pub fn run(bins: &Bins, program: &str, args: &[String], step: &str, quiet: bool) -> Result<()> {
    let (status, last) = wait_for(&bins.path(program), args, quiet, bins.time_limit)
        .map_err(|e| anyhow::anyhow!("stage {step}: {e:#}"))?;
    failed(step, status, &last)
}

/// Ok for a stage that succeeded; else the error saying which failed and its
/// last line ([`stage_error`]).
fn failed(step: &str, status: std::process::ExitStatus, last: &str) -> Result<()> {
    if status.success() {
        return Ok(());
    }
    Err(stage_error(status, format!("stage {step} failed ({status}): {}", last.trim())))
}

/// The error for a stage that exited with `status`, saying `message`: an
/// [`pm_stage::Unsupported`] one when it exited with
/// [`pm_stage::EXIT_UNSUPPORTED`], so the runner exits with that code too.
pub fn stage_error(status: std::process::ExitStatus, message: String) -> anyhow::Error {
    if status.code() == Some(pm_stage::EXIT_UNSUPPORTED as i32) {
        pm_stage::Unsupported(message).into()
    } else {
        anyhow::anyhow!(message)
    }
}

/// [`run`] for a program given by its path, with no time limit.
pub fn run_program(program: &Path, args: &[String], step: &str, quiet: bool) -> Result<()> {
    let (status, last) = wait_for(program, args, quiet, None)?;
    failed(step, status, &last)
}

/// [`run_program`] for a stage that may stop before its work is done, keeping
/// it (exit code [`pm_stage::EXIT_UNFINISHED`]): false when it did, true when it
/// finished.
pub fn run_resumable(program: &Path, args: &[String], step: &str, quiet: bool) -> Result<bool> {
    let (status, last) = wait_for(program, args, quiet, None)?;
    if status.code() == Some(pm_stage::EXIT_UNFINISHED as i32) {
        return Ok(false);
    }
    failed(step, status, &last)?;
    Ok(true)
}

/// Run `program` with `args` to its end: its exit status and the last line it
/// wrote on stderr (echoed unless `quiet`). With a `limit`, a program still
/// running after it is killed, and the error says it timed out.
fn wait_for(
    program: &Path,
    args: &[String],
    quiet: bool,
    limit: Option<std::time::Duration>,
) -> Result<(std::process::ExitStatus, String)> {
    let start = std::time::Instant::now();
    let mut child = Command::new(program)
        .args(args)
        .stdout(if quiet { Stdio::null() } else { Stdio::inherit() })
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("cannot start {}", program.display()))?;
    // The messages are read beside the wait, so a program that stops writing
    // cannot hold the wait past its limit.
    let err = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut last = String::new();
        for line in err.into_iter().flat_map(|e| BufReader::new(e).lines()) {
            let line = line.unwrap_or_default();
            // Progress lines (asked for by pm_stage::PROGRESS_LINES) go to
            // whoever watches this runner, even from a quiet stage.
            if !quiet || line.starts_with(pm_stage::PROGRESS_PREFIX) {
                let _ = writeln!(std::io::stderr(), "{line}");
            }
            if !line.trim().is_empty() {
                last = line;
            }
        }
        last
    });
    let status = match limit {
        None => child.wait().with_context(|| format!("{} did not finish", program.display()))?,
        Some(limit) => loop {
            if let Some(status) = child.try_wait().with_context(|| format!("{} did not finish", program.display()))? {
                break status;
            }
            if start.elapsed() > limit {
                let _ = child.kill();
                let _ = child.wait();
                bail!("{} timed out after {:.2} s and was stopped", program.display(), limit.as_secs_f64());
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        },
    };
    let last = reader.join().unwrap_or_default();
    Ok((status, last))
}

/// Run stage `name` quietly with `args` and `--stats-json stats` (its messages are
/// kept for the error if it fails) and read the statistics into its typed report
/// (`pm_stage::report`).
pub fn run_for_report<T: serde::de::DeserializeOwned>(
    bins: &Bins,
    name: &str,
    args: &[String],
    stats: &Path,
) -> Result<T> {
    let mut a = args.to_vec();
    a.extend(["--stats-json".to_string(), stats.display().to_string()]);
    run(bins, name, &a, name, true)?;
    read_stats(stats)
}

/// Read a stage's statistics file into its typed report.
pub fn read_stats<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("{}: not the statistics this runner reads", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: with CARGO_TARGET_DIR set, the runner said "photon-trace is
    /// missing" because it looked in target/release.
    #[test]
    fn binaries_are_found_where_cargo_puts_them() {
        let (root, cwd) = (Path::new("/repo"), Path::new("/home/u/work"));
        let at = |t: Option<&str>| target_dir_with(root, t.map(Into::into), cwd);
        assert_eq!(at(None), Path::new("/repo/target"));
        assert_eq!(at(Some("")), Path::new("/repo/target"));
        assert_eq!(at(Some("/tmp/t")), Path::new("/tmp/t"));
        assert_eq!(at(Some("build")), Path::new("/home/u/work/build"));
    }

    /// A stage that runs past the time limit is stopped and its step fails
    /// saying so, long before it would have ended; within the limit it runs to
    /// its end and its last message is kept.
    #[test]
    fn a_stage_past_its_time_limit_is_stopped() {
        let dir = tempfile::tempdir().unwrap();
        let sleeper = dir.path().join("photon-render");
        std::fs::write(&sleeper, "#!/bin/sh\necho started >&2\nsleep \"$1\"\necho done >&2\n").unwrap();
        std::fs::set_permissions(&sleeper, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
        let bins = Bins { dir: dir.path().to_path_buf(), time_limit: Some(std::time::Duration::from_millis(300)) };
        let start = std::time::Instant::now();
        let e = run(&bins, "photon-render", &["30".into()], "render", true).unwrap_err().to_string();
        assert!(e.contains("stage render") && e.contains("timed out"), "{e}");
        assert!(start.elapsed() < std::time::Duration::from_secs(5));
        run(&bins, "photon-render", &["0".into()], "render", true).unwrap();
        let (_, last) = wait_for(&sleeper, &["0".into()], true, bins.time_limit).unwrap();
        assert_eq!(last, "done");
    }
}
