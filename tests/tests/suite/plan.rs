//! The job plan (`cargo xtask plan`): the trace cut into slices and the render cut
//! into tiles give the same photon maps and image file as one trace and one render, the emitted Slurm scripts are valid bash chained in
//! dependency order, the OpenJD template carries the same graph, and the local
//! executor stops at a failing step with one line naming it. Progressive photon
//! mapping's independent runs average to the mean of the runs' images, and runs
//! stopped by a time budget and continued give the same image.

use pm_pipeline::jobs::{JobPlan, JobStep, openjd, slurm};
use pm_runner::bins::Bins;
use pm_runner::exec::execute;
use pm_runner::run::plan_for;
use pm_runner::run::{RunArgs, run_with};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn bins() -> Bins {
    pm_tests::bins()
}

fn args(dir: &Path, out: &str, tiles: u32, trace_slices: u32) -> RunArgs {
    let p = pm_tests::small_pipeline(dir, "cornell_spheres.gltf", "\"auto\"", 4, "pipeline");
    RunArgs { pipeline: Some(p), out: Some(dir.join(out)), tiles, trace_slices, workers: 2, ..Default::default() }
}

/// Three trace slices merged, and five tiles of the 24-row image (not dividing it
/// evenly) rendered as array tasks and assembled, give the photon maps and
/// image.exr byte for byte as one trace and one render do.
#[test]
fn a_sliced_and_tiled_run_writes_the_same_maps_and_image_as_one_run() {
    let dir = tempfile::tempdir().unwrap();
    run_with(&args(dir.path(), "whole", 1, 1), &root(), &bins()).unwrap();
    let outcomes = run_with(&args(dir.path(), "tiled", 5, 3), &root(), &bins()).unwrap();
    for step in ["photon-trace slices", "photon-trace merge", "photon-render tiles", "assemble"] {
        assert!(outcomes.iter().any(|o| o.step == step), "{step} not run: {outcomes:?}");
    }
    let read = |d: &str, f: &str| std::fs::read(dir.path().join(d).join(f)).unwrap();
    for f in ["global.pmap", "caustic.pmap", "image.exr"] {
        assert!(read("whole", f) == read("tiled", f), "{f} of the sliced, tiled run differs from one run's");
    }
    assert!(dir.path().join("tiled/tiles/tile-4.exr").exists());
    assert!(dir.path().join("tiled/slices/slice-2/global.pmap").exists());
}

/// The graph: each step after the steps that write its inputs; the tiles an array.
/// Slurm: every script passes `bash -n`; submit.sh submits in order, each job with
/// afterok on the jobs it waits for; the tile script is an array of 3 that reads
/// its index. OpenJD: the same steps and dependencies, the tiles a parameter space.
#[test]
fn emitted_slurm_scripts_and_openjd_template_carry_the_graph() {
    let dir = tempfile::tempdir().unwrap();
    let plan = plan_for(&args(dir.path(), "out", 3, 4), &root(), &bins()).unwrap();
    let names: Vec<&str> = plan.steps.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "photon-trace slices",
            "photon-trace merge",
            "photon-sort global",
            "photon-sort caustic",
            "photon-irradiance",
            "photon-render icache",
            "photon-render tiles",
            "assemble"
        ]
    );
    let step = |n: &str| plan.steps.iter().find(|s| s.name == n).unwrap();
    assert_eq!(step("photon-trace slices").tasks, 4);
    assert!(step("photon-trace slices").args.contains(&"{TASK}/4".to_string()));
    assert_eq!(step("photon-trace merge").after, ["photon-trace slices"]);
    assert_eq!(step("photon-sort global").after, ["photon-trace merge"]);
    assert_eq!(step("photon-irradiance").after, ["photon-sort global"]);
    assert_eq!(step("photon-render tiles").after, ["photon-sort caustic", "photon-irradiance", "photon-render icache"]);
    assert_eq!(step("photon-render tiles").tasks, 3);
    assert_eq!(step("assemble").after, ["photon-render tiles"]);

    let files = slurm(&plan);
    for (name, text) in &files {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let o = std::process::Command::new("bash").arg("-n").arg(&p).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let text = |n: &str| &files.iter().find(|f| f.0 == n).unwrap().1;
    let slices = text("00-photon-trace-slices.sbatch");
    assert!(slices.contains("#SBATCH --array=0-3") && slices.contains("'--slice' ''\"${TASK}\"'/4'"), "{slices}");
    let tiles = text("06-photon-render-tiles.sbatch");
    assert!(tiles.contains("#SBATCH --array=0-2") && tiles.contains("SLURM_ARRAY_TASK_ID"), "{tiles}");
    assert!(tiles.contains("'--tile' ''\"${TASK}\"'/3'"), "{tiles}");
    let submit = text("submit.sh");
    let lines: Vec<&str> = submit.lines().filter(|l| l.contains("sbatch")).collect();
    assert_eq!(lines.len(), 8);
    assert_eq!(lines[0], "job_0=$(sbatch --parsable 00-photon-trace-slices.sbatch)");
    assert_eq!(lines[1], "job_1=$(sbatch --parsable --dependency=afterok:${job_0} 01-photon-trace-merge.sbatch)");
    assert_eq!(
        lines[6],
        "job_6=$(sbatch --parsable --dependency=afterok:${job_3}:${job_4}:${job_5} 06-photon-render-tiles.sbatch)"
    );
    assert_eq!(lines[7], "job_7=$(sbatch --parsable --dependency=afterok:${job_6} 07-assemble.sbatch)");

    let t = openjd(&plan);
    assert_eq!(t["specificationVersion"], "jobtemplate-2023-09");
    let steps = t["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 8);
    assert_eq!(steps[0]["parameterSpace"]["taskParameterDefinitions"][0]["range"], "0-3");
    assert_eq!(steps[6]["parameterSpace"]["taskParameterDefinitions"][0]["range"], "0-2");
    assert_eq!(steps[6]["dependencies"].as_array().unwrap().len(), 3);
    let args: Vec<&str> = steps[6]["script"]["actions"]["onRun"]["args"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect();
    assert!(args.contains(&"{{Task.Param.Index}}/3"), "{args:?}");
    for s in steps {
        for d in s["dependencies"].as_array().into_iter().flatten() {
            assert!(steps.iter().any(|o| o["name"] == d["dependsOn"]), "{d}");
        }
    }
}

/// A failing task stops the local executor with one line naming the step and the
/// task; what earlier steps wrote stays.
#[test]
fn the_local_executor_names_the_failing_task() {
    let dir = tempfile::tempdir().unwrap();
    let kept = dir.path().join("kept.txt");
    let sh = |script: String| JobStep {
        name: "writes".into(),
        program: "/bin/sh".into(),
        args: vec!["-c".into(), script],
        tasks: 1,
        first_task: 0,
        inputs: vec![],
        outputs: vec![],
        after: vec![],
        resumable: false,
    };
    let plan = JobPlan {
        out: dir.path().display().to_string(),
        steps: vec![
            sh(format!("echo ok > {}", kept.display())),
            JobStep {
                name: "breaks".into(),
                tasks: 3,
                ..sh("if [ {TASK} = 1 ]; then echo 'stage: error: bad tile' >&2; exit 3; fi".into())
            },
        ],
    };
    let e = execute(&plan, 2).unwrap_err().to_string();
    assert!(e.contains("breaks (task 1 of 3) failed") && e.contains("bad tile") && !e.contains('\n'), "{e}");
    assert_eq!(std::fs::read_to_string(&kept).unwrap(), "ok\n");
}

/// The frames dimension: `cargo xtask live --frame-tasks 3` runs the live plan
/// (three runs of frames as array tasks, then assembly) and writes the preview one
/// run writes; the plan's Slurm scripts pass `bash -n` and the frame step is an
/// array of 3 that the assembly waits for.
#[test]
fn an_animation_in_frame_tasks_writes_what_one_run_writes() {
    let dir = tempfile::tempdir().unwrap();
    let root = root();
    let pipeline = dir.path().join("live.toml");
    std::fs::copy(root.join("pipeline.toml"), &pipeline).unwrap();
    pm_tests::edit_pipeline(&pipeline, |p| {
        p.scene = root.join(&p.scene);
        p.live_scene = Some(root.join("scenes/jozwowski_room_16.gltf"));
        (p.live.vertex.per_frame, p.live.vertex.total) = (300, 900);
        (p.live.frame.width, p.live.frame.height) = (24, 16);
    });
    let args = |out: &str, frame_tasks: u32| pm_runner::run::LiveArgs {
        pipeline: Some(pipeline.clone()),
        out: Some(dir.path().join(out)),
        frames: 5,
        frame_tasks,
        workers: 2,
        ..Default::default()
    };
    let plan = pm_runner::run::live_plan(&args("split", 3), &root, &bins()).unwrap();
    assert_eq!(plan.steps.len(), 2);
    assert_eq!((plan.steps[0].tasks, plan.steps[1].after.as_slice()), (3, &["photon-live frames".to_string()][..]));
    for (name, text) in slurm(&plan) {
        let p = dir.path().join(&name);
        std::fs::write(&p, &text).unwrap();
        let o = std::process::Command::new("bash").arg("-n").arg(&p).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
    }
    execute(&plan, 2).unwrap();
    let one = args("one", 1);
    let set_args = {
        // One run, as `cargo xtask live` makes it.
        let plan = pm_runner::run::live_plan(&one, &root, &bins()).unwrap();
        let a = &plan.steps[0].args;
        assert_eq!(a[a.len() - 2..], ["--frame-task".to_string(), "{TASK}/1".to_string()]);
        a[..a.len() - 2].to_vec()
    };
    let o = std::process::Command::new(bins().path("photon-live")).args(&set_args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = |d: &str, f: &str| std::fs::read(dir.path().join(d).join(f)).unwrap();
    assert!(read("one", "live.apng") == read("split", "live.apng"), "the assembled preview differs from one run's");
    assert!(read("one", "frames/0004.png") == read("split", "frames/0004.png"));
}

/// Progressive photon mapping as K runs (issue 39): `cargo xtask run --method
/// sppm --runs 3` runs photon-render as 3 array tasks with seeds seed, seed + 1
/// and seed + 2 and averages them: image.exr holds the mean of three one-run
/// renders with those seeds, exactly. With a tiny `--run-time-budget` every run
/// stops after each pass (exit 75) and is run again from its state until its
/// passes are done: the same image, byte for byte. The Slurm script of the runs
/// asks to be re-queued and, run with a stand-in `scontrol`, re-queues its own
/// array task on exit 75; tiles and runs of other methods are refused.
#[test]
fn sppm_runs_average_and_continue_after_a_time_budget() {
    let dir = tempfile::tempdir().unwrap();
    let p = pm_tests::small_pipeline(dir.path(), "cornell_boxes.gltf", "\"auto\"", 1, "sppm");
    pm_tests::edit_pipeline(&p, |c| (c.sppm.passes, c.sppm.photons_per_pass) = (4, 2_000));
    let base = pm_pipeline::Pipeline::load(&p).unwrap().seed;
    let run = |out: &str, runs: u32, budget: Option<f64>, pipeline: &Path| {
        let a = RunArgs {
            pipeline: Some(pipeline.to_owned()),
            out: Some(dir.path().join(out)),
            method: Some(pm_methods::Method::Sppm),
            runs,
            run_time_budget: budget,
            workers: 2,
            ..Default::default()
        };
        run_with(&a, &root(), &bins()).unwrap()
    };
    let outcomes = run("three", 3, None, &p);
    let steps: Vec<&str> = outcomes.iter().map(|o| o.step.as_str()).collect();
    assert_eq!(steps, ["photon-render runs", "average runs"]);
    let singles: Vec<pm_image::Layers> = (0..3)
        .map(|k| {
            let q = dir.path().join(format!("seed{k}.toml"));
            std::fs::copy(&p, &q).unwrap();
            pm_tests::edit_pipeline(&q, |c| c.seed = base + k);
            run(&format!("seed{k}"), 1, None, &q);
            pm_image::read_exr(&dir.path().join(format!("seed{k}/image.exr"))).unwrap()
        })
        .collect();
    let mean = pm_image::average(&singles).unwrap();
    assert_eq!(pm_image::read_exr(&dir.path().join("three/image.exr")).unwrap(), mean);
    run("budget", 3, Some(1e-6), &p);
    let read = |d: &str| std::fs::read(dir.path().join(d).join("image.exr")).unwrap();
    assert!(read("budget") == read("three"), "runs continued from their states differ from runs in one go");
    assert_eq!(pm_format::read_state(&dir.path().join("budget/runs/run-2.state")).unwrap().passes, 4);

    // Slurm: the runs' script asks to be re-queued, and re-queues its own task
    // when photon-render stops at its budget (a stand-in scontrol records it).
    let a = RunArgs {
        pipeline: Some(p.clone()),
        out: Some(dir.path().join("planned")),
        method: Some(pm_methods::Method::Sppm),
        runs: 2,
        run_time_budget: Some(1e-6),
        ..Default::default()
    };
    let plan = plan_for(&a, &root(), &bins()).unwrap();
    let files = slurm(&plan);
    let (_, script) = files.iter().find(|(n, _)| n.contains("photon-render-runs")).unwrap();
    assert!(script.contains("#SBATCH --requeue") && script.contains("#SBATCH --array=0-1"), "{script}");
    let bin = dir.path().join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let record = dir.path().join("requeued.txt");
    let fake = bin.join("scontrol");
    std::fs::write(&fake, format!("#!/bin/sh\necho \"$@\" >> {}\n", record.display())).unwrap();
    std::fs::set_permissions(&fake, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let sbatch = dir.path().join("runs.sbatch");
    std::fs::write(&sbatch, script).unwrap();
    let o = std::process::Command::new("bash")
        .arg(&sbatch)
        .env("PATH", format!("{}:{}", bin.display(), std::env::var("PATH").unwrap()))
        .env("SLURM_ARRAY_JOB_ID", "77")
        .env("SLURM_ARRAY_TASK_ID", "1")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&record).unwrap(), "requeue 77_1\n");
    assert_eq!(pm_format::read_state(&dir.path().join("planned/runs/run-1.state")).unwrap().passes, 1);
    // What a plan cannot cut so.
    let e = plan_for(&RunArgs { tiles: 2, ..a.clone() }, &root(), &bins()).unwrap_err().to_string();
    assert!(e.contains("--runs instead"), "{e}");
    let e =
        plan_for(&RunArgs { method: Some(pm_methods::Method::Path), ..a }, &root(), &bins()).unwrap_err().to_string();
    assert!(e.contains("progressive photon mapping's"), "{e}");
}

/// An animation in the job plan: `frames = [24, 25]` plans every step as an array
/// of one task per frame (the frame's index), each frame's photon maps and image
/// in its own folder, and the frames equal the same frames rendered one by one
/// (`frame = F`) byte for byte; the Slurm scripts give the array its frame
/// numbers.
#[test]
fn an_animations_frame_tasks_equal_its_frames_rendered_one_by_one() {
    let dir = tempfile::tempdir().unwrap();
    let scene = root().join("tests/scenes/blender_room/blender_room.gltf");
    let write = |name: &str, frames: Option<[u32; 2]>, frame: Option<u32>| {
        let p = pm_tests::small_pipeline(dir.path(), &scene.display().to_string(), "\"auto\"", 4, name);
        pm_tests::edit_pipeline(&p, |p| {
            (p.frames, p.scene_options.frame, p.scene_options.fps) = (frames, frame, Some(24.0));
        });
        p
    };
    let frames = write("frames", Some([24, 25]), None);
    let args = RunArgs { pipeline: Some(frames), out: Some(dir.path().join("anim")), workers: 2, ..Default::default() };
    let plan = plan_for(&args, &root(), &bins()).unwrap();
    assert!(plan.steps.iter().all(|s| (s.first_task, s.tasks) == (24, 2)), "{:?}", plan.steps);
    assert!(
        plan.steps
            .iter()
            .filter(|s| s.args.iter().any(|a| a == "--scene"))
            .all(|s| s.args.ends_with(&["--frame".into(), "{TASK}".into()]))
    );
    let sbatch = slurm(&plan);
    assert!(sbatch.iter().filter(|(n, _)| n.ends_with(".sbatch")).all(|(_, t)| t.contains("#SBATCH --array=24-25")));
    run_with(&args, &root(), &bins()).unwrap();
    for f in [24u32, 25] {
        let one = write(&format!("frame{f}"), None, Some(f));
        let out = dir.path().join(format!("one-{f}"));
        run_with(&RunArgs { pipeline: Some(one), out: Some(out.clone()), ..Default::default() }, &root(), &bins())
            .unwrap();
        for file in ["global.pmap", "image.exr"] {
            let a = std::fs::read(dir.path().join(format!("anim/frame-{f}")).join(file)).unwrap();
            assert!(a == std::fs::read(out.join(file)).unwrap(), "frame {f}: {file} differs");
        }
    }
    let (a, b) = (
        std::fs::read(dir.path().join("anim/frame-24/image.exr")).unwrap(),
        std::fs::read(dir.path().join("anim/frame-25/image.exr")).unwrap(),
    );
    assert!(a != b, "the lamp and the box move between frames");
}
