//! `cargo xtask slurm-selftest`: the emitted Slurm job run on a real Slurm. Needs
//! root on Debian or Ubuntu; not part of CI. Installs slurmctld, slurmd,
//! slurm-client and munge from the distribution, starts a one-node cluster (munged,
//! slurmctld, slurmd, with a minimal slurm.conf written here) unless one answers
//! already, submits the job plan of the default pipeline with 4 trace slices and 4
//! tiles, waits for it, and compares its photon maps and image with
//! `cargo xtask run`'s (one trace, one render) byte for byte.

use anyhow::{Context, Result, bail, ensure};
use pm_pipeline::jobs::slurm;
use pm_runner::bins::Bins;
use pm_runner::run::plan_for;
use pm_runner::run::{RunArgs, run_with};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// Options of `cargo xtask slurm-selftest`.
#[derive(clap::Args, Debug)]
// Help texts give units as [m] and [s], not links.
#[allow(rustdoc::broken_intra_doc_links)]
pub struct Args {
    /// Tiles of the render (array tasks).
    #[arg(long, default_value_t = 4)]
    pub tiles: u32,
    /// Slices of the photon trace (array tasks).
    #[arg(long, default_value_t = 4)]
    pub trace_slices: u32,
    /// Give up waiting for the job after this long [s].
    #[arg(long, default_value_t = 1800)]
    pub timeout: u64,
}

fn sh(cmd: &str) -> Result<String> {
    let o = Command::new("sh").args(["-c", cmd]).output().with_context(|| format!("cannot run: {cmd}"))?;
    ensure!(o.status.success(), "{cmd}: {}", String::from_utf8_lossy(&o.stderr).trim());
    Ok(String::from_utf8_lossy(&o.stdout).trim().to_string())
}

/// Install and start a one-node cluster unless `sinfo` answers already.
fn cluster() -> Result<()> {
    if sh("sinfo -h -o %T").is_ok_and(|s| s.contains("idle") || s.contains("mix") || s.contains("alloc")) {
        return Ok(());
    }
    ensure!(sh("id -u")? == "0", "slurm-selftest needs root (it installs and starts Slurm)");
    ensure!(Path::new("/etc/debian_version").exists(), "slurm-selftest needs Debian or Ubuntu (apt-get)");
    println!("installing slurmctld, slurmd, slurm-client, munge");
    sh("DEBIAN_FRONTEND=noninteractive apt-get install -y -q slurmctld slurmd slurm-client munge")?;
    sh("[ -s /etc/munge/munge.key ] || dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 2>/dev/null")?;
    sh(
        "mkdir -p /run/munge /var/log/munge /var/lib/munge && chown munge:munge /etc/munge/munge.key /run/munge /var/log/munge /var/lib/munge && chmod 400 /etc/munge/munge.key",
    )?;
    if sh("munge -n | unmunge").is_err() {
        sh("runuser -u munge -- /usr/sbin/munged")?;
    }
    let host = sh("hostname -s")?;
    let cpus = sh("nproc")?;
    let conf = format!(
        "ClusterName=pmselftest\nSlurmctldHost={host}\nAuthType=auth/munge\nCredType=cred/munge\n\
         ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nSlurmUser=root\nReturnToService=2\n\
         SlurmctldPidFile=/tmp/slurm/slurmctld.pid\nSlurmdPidFile=/tmp/slurm/slurmd.pid\n\
         SlurmdSpoolDir=/tmp/slurm/d\nStateSaveLocation=/tmp/slurm/ctld\n\
         SlurmctldLogFile=/tmp/slurm/slurmctld.log\nSlurmdLogFile=/tmp/slurm/slurmd.log\n\
         SchedulerType=sched/builtin\nSelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n\
         MpiDefault=none\nJobCompType=jobcomp/none\nAccountingStorageType=accounting_storage/none\n\
         NodeName={host} CPUs={cpus} State=UNKNOWN\nPartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n"
    );
    // A fresh cluster: state from an earlier one (another cluster name) stops slurmctld.
    sh("rm -rf /tmp/slurm/d /tmp/slurm/ctld && mkdir -p /etc/slurm /tmp/slurm/d /tmp/slurm/ctld")?;
    std::fs::write("/etc/slurm/slurm.conf", conf).context("/etc/slurm/slurm.conf: cannot write")?;
    sh("/usr/sbin/slurmctld").map_err(|e| {
        let log = std::fs::read_to_string("/tmp/slurm/slurmctld.log").unwrap_or_default();
        anyhow::anyhow!("{e} {}", log.lines().rfind(|l| l.contains("fatal") || l.contains("error")).unwrap_or(""))
    })?;
    std::thread::sleep(Duration::from_secs(2));
    sh("/usr/sbin/slurmd")?;
    for _ in 0..30 {
        if sh("sinfo -h -o %T").is_ok_and(|s| s.contains("idle")) {
            return Ok(());
        }
        std::thread::sleep(Duration::from_secs(1));
    }
    bail!("the Slurm node did not come up (see /tmp/slurm/*.log)")
}

/// Run the self-test.
pub fn run(args: &Args, root: &Path) -> Result<()> {
    cluster()?;
    let versions = format!("{}, {}", sh("sinfo -V")?, sh("munged -V 2>&1 | head -1")?);
    println!("cluster up: {versions}");
    let bins = Bins::build(root)?;
    let base = root.join("out/slurm-selftest");
    let _ = std::fs::remove_dir_all(&base);
    let (jobs, out, reference) = (base.join("jobs"), base.join("out"), base.join("reference"));
    std::fs::create_dir_all(&jobs)?;
    let plan_args =
        RunArgs { out: Some(out.clone()), tiles: args.tiles, trace_slices: args.trace_slices, ..Default::default() };
    let plan = plan_for(&plan_args, root, &bins)?;
    for (name, text) in slurm(&plan) {
        std::fs::write(jobs.join(name), text)?;
    }
    let t = Instant::now();
    println!("{}", sh(&format!("bash {}", jobs.join("submit.sh").display()))?);
    while !sh("squeue -h")?.is_empty() {
        ensure!(t.elapsed().as_secs() < args.timeout, "the job did not finish within {} s", args.timeout);
        std::thread::sleep(Duration::from_millis(500));
    }
    let slurm_secs = t.elapsed().as_secs_f64();
    ensure!(out.join("image.exr").exists(), "the Slurm job wrote no image (logs in {})", jobs.join("logs").display());
    let t = Instant::now();
    run_with(&RunArgs { out: Some(reference.clone()), ..Default::default() }, root, &bins)?;
    let local_secs = t.elapsed().as_secs_f64();
    for f in ["global.pmap", "caustic.pmap", "image.exr", "image.png"] {
        let (a, b) = (std::fs::read(out.join(f))?, std::fs::read(reference.join(f))?);
        ensure!(a == b, "{f}: the Slurm job's differs from cargo xtask run's");
    }
    println!(
        "slurm-selftest passed: {} steps ({} trace slices, {} tiles) through Slurm in {slurm_secs:.1} s (submission \
         to last job), cargo xtask run {local_secs:.1} s; photon maps, image.exr and image.png byte-identical. {versions}",
        plan.steps.len(),
        args.trace_slices,
        args.tiles
    );
    Ok(())
}
