//! Sweeps end to end: expansion, validation, resume after a kill, shards and
//! merge, thread-count independence.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command as Std;
use std::time::Duration;

use assert_cmd::Command;
use hertz_cradle::error::Source;
use hertz_cradle::sweep::Sweep;

fn cradle() -> Command {
    Command::cargo_bin("cradle").unwrap()
}

fn sweep_text(text: &str) -> Result<Sweep, String> {
    Sweep::parse(&Source::new("sweep.toml", text), Path::new(".")).map_err(|e| e.to_string())
}

const SMALL: &str = r#"
[scene]
balls = 5
velocity = [1.0, 0, 0, 0, 0]

[[axis]]
param = "mass[2]"
logspace = [0.01, 1.0, 3]

[[axis]]
param = "gap"
linspace = [0.0, 2e-5, 4]
"#;

#[test]
fn expansion_is_row_major_with_exact_values() {
    let s = sweep_text(SMALL).unwrap();
    assert_eq!((s.total, s.width), (12, 5));
    assert_eq!(s.axis_names(), ["mass[2]", "gap"]);
    // first axis slowest
    assert_eq!(s.indices(0), [0, 0]);
    assert_eq!(s.indices(1), [0, 1]);
    assert_eq!(s.indices(4), [1, 0]);
    assert_eq!(s.indices(11), [2, 3]);
    let sc = s.scene(7).unwrap();
    assert_eq!(sc.mass[2], (0.5 * 0.01f64.ln()).exp()); // 0.1, geometric middle
    assert!((sc.mass[2] - 0.1).abs() < 1e-15);
    // Both ends of a logspace exactly as written (exp(ln 0.01) is
    // 0.010000000000000004: a filter on 0.01 found nothing).
    assert_eq!(s.scene(0).unwrap().mass[2], 0.01);
    assert_eq!(s.scene(11).unwrap().mass[2], 1.0);
    assert_eq!(s.axis_fields(0)[0], "0.01");
    assert_eq!(sc.mass[0], s.base.mass[0]);
    assert_eq!(sc.gap, vec![3.0 * (2e-5 / 3.0); 4]);
    assert_eq!(s.scene(11).unwrap().gap[0], 2e-5);
    // CSV axis columns round-trip the exact values
    let f: Vec<f64> = s
        .axis_fields(5)
        .iter()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(f, [s.scene(5).unwrap().mass[2], s.scene(5).unwrap().gap[0]]);
    assert_eq!(f[1], 0.0 + 1.0 * ((2e-5 - 0.0) / 3.0));
}

#[test]
fn glue_and_balls_axes() {
    let s = sweep_text(
        "[scene]\nballs = 4\n[scene.launch]\nballs = 1\nvelocity = 1.0\n[[axis]]\nparam = \"balls\"\nvalues = [3, 6]\n[[axis]]\nparam = \"launch.balls\"\nvalues = [1, 2]\n",
    )
    .unwrap();
    assert_eq!((s.total, s.width), (4, 6));
    assert_eq!(s.scene(3).unwrap().velocity, [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    let g = sweep_text("[scene]\nballs = 3\nvelocity = [1, 1, 0]\n[[axis]]\nparam = \"glue\"\nvalues = [\"--\", \"=-\"]\n").unwrap();
    assert_eq!(g.scene(1).unwrap().glue, [true, false]);
}

#[test]
fn each_validation_error_is_clear() {
    let base = "[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n";
    let cases = [
        ("[[axis]]\nparam = \"mas[2]\"\nvalues = [1.0]\n", "did you mean `mass`"),
        ("[[axis]]\nparam = \"mass[7]\"\nvalues = [1.0]\n", "index 7"),
        ("[[axis]]\nparam = \"gap\"\nlinspace = [0, 1e-5, 0]\n", "at least 1 point"),
        ("[[axis]]\nparam = \"gap\"\nvalues = []\n", "at least one value"),
        ("[[axis]]\nparam = \"gap\"\nvalues = [1.0]\nlinspace = [0, 1, 2]\n", "exactly one of"),
        ("[[axis]]\nparam = \"mass\"\nlogspace = [0, 1, 3]\n", "must be > 0"),
        ("[[axis]]\nparam = \"gap\"\nvalues = [-1.0]\n", "invalid scene"),
        ("[[axis]]\nparam = \"gap\"\nlinspace = [0, 1, 100000]\n[[axis]]\nparam = \"mass\"\nlinspace = [1, 2, 100000]\n", "≤ 1000000000 scenes"),
        ("[[axis]]\nparam = \"gap\"\nlinspace = [0, 1, 2]\nstep = 3\n", "unknown key `step`"),
    ];
    for (axes, want) in cases {
        let e = sweep_text(&format!("{base}{axes}")).unwrap_err();
        assert!(
            e.contains(want) && e.contains("sweep.toml"),
            "{axes:?}: {e}"
        );
    }
    let e = sweep_text("scene = \"nope.toml\"\n").unwrap_err();
    assert!(e.contains("nope.toml"), "{e}");
    let e =
        sweep_text("[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\nradus = 1\n").unwrap_err();
    assert!(
        e.contains("sweep.toml:4") && e.contains("did you mean `radius`"),
        "{e}"
    );
}

fn write_sweep(dir: &Path, n_mass: usize, n_gap: usize) -> PathBuf {
    let p = dir.join("sweep.toml");
    fs::write(
        dir.join("scene.toml"),
        "balls = 5\nvelocity = [1.0, 0, 0, 0, 0]\n",
    )
    .unwrap();
    fs::write(
        &p,
        format!("scene = \"scene.toml\"\n[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.01, 0.5, {n_mass}]\n[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 2e-5, {n_gap}]\n"),
    )
    .unwrap();
    p
}

fn sweep(args: &[&str]) {
    cradle().arg("sweep").args(args).assert().success();
}

#[test]
fn shards_merge_to_the_full_run_and_threads_do_not_matter() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 7, 9);
    let s = sw.to_str().unwrap();
    let p = |n: &str| d.join(n).display().to_string();
    sweep(&[
        s,
        "--out",
        &p("full.csv"),
        "--backend",
        "cpu",
        "--threads",
        "2",
    ]);
    sweep(&[
        s,
        "--out",
        &p("one.csv"),
        "--backend",
        "cpu",
        "--threads",
        "1",
    ]);
    let full = fs::read(p("full.csv")).unwrap();
    assert_eq!(
        full,
        fs::read(p("one.csv")).unwrap(),
        "bytes depend on the thread count"
    );
    assert_eq!(full.iter().filter(|&&b| b == b'\n').count(), 64);
    for k in 1..=3 {
        sweep(&[
            s,
            "--out",
            &p(&format!("part{k}.csv")),
            "--backend",
            "cpu",
            "--shard",
            &format!("{k}/3"),
        ]);
    }
    cradle()
        .args([
            "merge",
            &p("part3.csv"),
            &p("part1.csv"),
            &p("part2.csv"),
            "--out",
            &p("merged.csv"),
        ])
        .assert()
        .success();
    assert_eq!(full, fs::read(p("merged.csv")).unwrap());
    // a missing or repeated shard is refused
    let out = cradle()
        .args([
            "merge",
            &p("part1.csv"),
            &p("part3.csv"),
            "--out",
            &p("bad.csv"),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("missing"));
    let out = cradle()
        .args([
            "merge",
            &p("part1.csv"),
            &p("part1.csv"),
            &p("part2.csv"),
            &p("part3.csv"),
            "--out",
            &p("bad.csv"),
        ])
        .output()
        .unwrap();
    assert!(
        !out.status.success() && String::from_utf8_lossy(&out.stderr).contains("more than once")
    );
    assert!(!d.join("bad.csv").exists());
    // the sidecar says how the file was made
    let meta: serde_json::Value =
        serde_json::from_slice(&fs::read(p("full.csv.json")).unwrap()).unwrap();
    assert_eq!(meta["backend"], "cpu");
    assert_eq!(meta["total_scenes"], 63);
    assert!(meta["scenes_per_s"].as_f64().unwrap() > 0.0);
}

#[test]
fn resume_after_kill_gives_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 40, 200); // 8000 scenes, a few seconds
    let s = sw.to_str().unwrap();
    let full = d.join("full.csv");
    let cut = d.join("cut.csv");
    sweep(&[s, "--out", full.to_str().unwrap(), "--backend", "cpu"]);
    let bin = assert_cmd::cargo::cargo_bin("cradle");
    let mut child = Std::new(&bin)
        .args([
            "sweep",
            s,
            "--out",
            cut.to_str().unwrap(),
            "--backend",
            "cpu",
        ])
        .spawn()
        .unwrap();
    // kill -9 once some rows are on disk
    let partial = d.join("cut.csv.partial");
    let t0 = std::time::Instant::now();
    while fs::metadata(&partial).map(|m| m.len()).unwrap_or(0) < 2000
        && t0.elapsed() < Duration::from_secs(60)
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!cut.exists(), "an interrupted run must not look complete");
    assert!(partial.exists());
    // append a torn row, as a crash mid-write would
    let mut bytes = fs::read(&partial).unwrap();
    bytes.extend_from_slice(b"99999,0.1,0.0,o");
    fs::write(&partial, bytes).unwrap();
    sweep(&[
        s,
        "--out",
        cut.to_str().unwrap(),
        "--backend",
        "cpu",
        "--resume",
    ]);
    assert_eq!(fs::read(&full).unwrap(), fs::read(&cut).unwrap());
    assert!(!partial.exists());
    // resuming a complete run does nothing; resuming another sweep is refused
    sweep(&[s, "--out", cut.to_str().unwrap(), "--resume"]);
    let meta: serde_json::Value =
        serde_json::from_slice(&fs::read(d.join("cut.csv.json")).unwrap()).unwrap();
    assert!(meta["resumed_from_row"].as_u64().unwrap() > 0);
}

#[test]
fn resume_refuses_a_different_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 2, 2);
    let out = d.join("o.csv");
    fs::write(d.join("o.csv.partial"), "id\n").unwrap();
    fs::write(d.join("o.csv.partial.spec"), "something else").unwrap();
    let o = cradle()
        .args([
            "sweep",
            sw.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--resume",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("different sweep"));
}

#[test]
fn bad_sweep_flags_exit_2_and_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 2, 2);
    let s = sw.to_str().unwrap();
    let out = d.join("o.csv");
    let o = out.to_str().unwrap();
    for args in [
        vec![s, "--out", o, "--shard", "0/3"],
        vec![s, "--out", o, "--shard", "x"],
        vec![s, "--out", o, "--precision", "f16"],
        vec![s, "--out", o, "--tolerance", "-1"],
        vec![s, "--out", o, "--method", "euler"],
        vec![s, "--out", "/no/such/dir/o.csv"],
        vec!["/no/such/sweep.toml", "--out", o],
    ] {
        let r = cradle().arg("sweep").args(&args).output().unwrap();
        assert_eq!(
            r.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert!(
            !out.exists() && !d.join("o.csv.partial").exists(),
            "{args:?}"
        );
    }
}

#[test]
fn shards_are_balanced_in_cost_not_count() {
    use hertz_cradle::engine::Overrides;
    // Chains of 2 … 48 balls: the last scenes cost far more than the first.
    let s = sweep_text(
        "[scene]\nballs = 2\n[scene.launch]\nvelocity = 1.0\n[[axis]]\nparam = \"balls\"\nvalues = [2, 4, 8, 16, 24, 32, 48]\n[[axis]]\nparam = \"launch.velocity\"\nlinspace = [0.5, 1.5, 6]\n",
    );
    let s = s.unwrap();
    let o = Overrides::default();
    let ranges: Vec<(u64, u64)> = (1..=3).map(|k| s.shard_range(Some((k, 3)), &o)).collect();
    assert_eq!(ranges[0].0, 0);
    assert_eq!(ranges[2].1, s.total);
    assert!(ranges.windows(2).all(|w| w[0].1 == w[1].0), "{ranges:?}");
    // the measured work (steps × bodies) of each shard
    let work = |(lo, hi): (u64, u64)| -> f64 {
        (lo..hi)
            .map(|id| {
                let scene = s.scene(id).unwrap();
                let ch = hertz_cradle::engine::Chain::from_scene(&scene).unwrap();
                let solver = hertz_cradle::engine::Solver::resolve(&scene, &o).unwrap();
                let out = hertz_cradle::engine::simulate_chain(
                    &ch,
                    &solver,
                    &mut hertz_cradle::engine::Silent,
                );
                out.steps as f64 * ch.n_bodies() as f64
            })
            .sum()
    };
    let w: Vec<f64> = ranges.iter().map(|&r| work(r)).collect();
    let count: Vec<f64> = (0..3)
        .map(|k| work((k * s.total / 3, (k + 1) * s.total / 3)))
        .collect();
    let spread = |w: &[f64]| {
        w.iter().cloned().fold(0.0, f64::max) / w.iter().cloned().fold(f64::MAX, f64::min)
    };
    eprintln!(
        "work per shard: by cost {w:?} (max/min {:.2}), by count {count:?} (max/min {:.1})",
        spread(&w),
        spread(&count)
    );
    // 42 scenes of very different cost cannot split evenly into contiguous thirds
    assert!(spread(&w) < 3.0, "{w:?}");
    assert!(
        spread(&count) > 5.0,
        "the test sweep must be unbalanced by count: {count:?}"
    );
}

#[test]
fn shard_slurm_reads_the_job_array() {
    use hertz_cradle::sweep::shard::slurm_shard;
    let env = |vars: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    };
    let ok = slurm_shard(env(&[
        ("SLURM_ARRAY_TASK_ID", "3"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
    ]));
    assert_eq!(ok.unwrap(), (3, 4));
    // arrays numbered from 0
    let ok = slurm_shard(env(&[
        ("SLURM_ARRAY_TASK_ID", "0"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
        ("SLURM_ARRAY_TASK_MIN", "0"),
    ]));
    assert_eq!(ok.unwrap(), (1, 4));
    let e = slurm_shard(env(&[("SLURM_ARRAY_TASK_COUNT", "4")]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("SLURM_ARRAY_TASK_ID") && e.contains("K/N"),
        "{e}"
    );
    let e = slurm_shard(env(&[
        ("SLURM_ARRAY_TASK_ID", "9"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]))
    .unwrap_err()
    .to_string();
    assert!(e.contains("outside"), "{e}");
    // the CLI without a job array: exit 2, no output
    let dir = tempfile::tempdir().unwrap();
    let sw = write_sweep(dir.path(), 2, 2);
    let out = dir.path().join("o.csv");
    let r = cradle()
        .args([
            "sweep",
            sw.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--shard",
            "slurm",
        ])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert!(!out.exists());
}

/// Slurm commands and daemons present (Debian's slurm-wlm and munge)?
fn slurm_installed() -> bool {
    ["sbatch", "slurmctld", "slurmd", "munged"].iter().all(|c| {
        Std::new("sh")
            .args(["-c", &format!("command -v {c} || test -x /usr/sbin/{c}")])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// Wait until none of `jobs` is queued or running.
fn wait_for(jobs: &[&str]) {
    let t0 = std::time::Instant::now();
    loop {
        let q = Std::new("squeue")
            .args(["-h", "-j", &jobs.join(",")])
            .output()
            .unwrap();
        if String::from_utf8_lossy(&q.stdout).trim().is_empty() {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "Slurm jobs {jobs:?} still queued after 300 s"
        );
        std::thread::sleep(Duration::from_millis(300));
    }
}

/// Submit a batch script (`sbatch --parsable`, `extra` first), wait for it
/// as `wait_for` does (every 300 ms: `sbatch --wait` polls every 2 s and
/// more), and return whether it completed (scontrol's JobState).
fn sbatch_and_wait(extra: &[&str], script: &str) -> bool {
    let sub = Std::new("sbatch")
        .arg("--parsable")
        .args(extra)
        .arg(script)
        .output()
        .unwrap();
    assert!(
        sub.status.success(),
        "sbatch {script}: {}",
        String::from_utf8_lossy(&sub.stderr)
    );
    let id = String::from_utf8(sub.stdout).unwrap();
    let id = id.trim().split(';').next().unwrap().to_string();
    wait_for(&[&id]);
    let show = Std::new("scontrol")
        .args(["-o", "show", "job", &id])
        .output()
        .unwrap();
    let show = String::from_utf8_lossy(&show.stdout);
    assert!(show.contains("JobState="), "scontrol show job {id}: {show}");
    show.contains("JobState=COMPLETED")
}

#[test]
fn slurm_job_array_merges_to_the_unsharded_run() {
    if !slurm_installed() {
        if std::env::var("CRADLE_REQUIRE_SLURM").as_deref() == Ok("1") {
            panic!("CRADLE_REQUIRE_SLURM=1 but Slurm is not installed (apt-get install slurm-wlm munge)");
        }
        eprintln!("SKIPPED: Slurm is not installed (apt-get install slurm-wlm munge; CRADLE_REQUIRE_SLURM=1 makes this a failure)");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let up = Std::new(root.join("scripts/slurm_local.sh"))
        .arg("start")
        .output()
        .unwrap();
    assert!(
        up.status.success(),
        "slurm_local.sh start: {}",
        String::from_utf8_lossy(&up.stderr)
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 6, 5);
    let s = sw.to_str().unwrap();
    let p = |n: &str| d.join(n).display().to_string();
    sweep(&[s, "--out", &p("full.csv"), "--backend", "cpu"]);
    let exe = env!("CARGO_BIN_EXE_cradle");
    cradle()
        .args([
            "slurm",
            s,
            "--shards",
            "4",
            "--out",
            &p("merged.csv"),
            "--dir",
            &p("job"),
            "--cradle",
            exe,
        ])
        .assert()
        .success();
    let sub = Std::new(d.join("job/submit.sh")).output().unwrap();
    assert!(
        sub.status.success(),
        "submit: {}",
        String::from_utf8_lossy(&sub.stderr)
    );
    let ids = String::from_utf8(sub.stdout).unwrap();
    let ids: Vec<&str> = ids.split_whitespace().collect();
    assert_eq!(ids.len(), 2, "{ids:?}");
    wait_for(&ids);
    let merged = fs::read(p("merged.csv")).unwrap_or_else(|e| {
        panic!(
            "no merged output ({e}); merge log: {}",
            fs::read_to_string(d.join("job/logs/merge.out")).unwrap_or_default()
        )
    });
    assert_eq!(
        fs::read(p("full.csv")).unwrap(),
        merged,
        "merged Slurm output differs from the unsharded run"
    );
    // A lost shard: the merge says which and how to resubmit; shard 2 alone,
    // then the merge again, gives the same bytes.
    fs::remove_file(d.join("job/parts/shard-2-of-4.csv")).unwrap();
    fs::remove_file(p("merged.csv")).unwrap();
    assert!(!sbatch_and_wait(&[], &p("job/merge.sbatch")));
    let log = fs::read_to_string(d.join("job/logs/merge.out")).unwrap();
    assert!(
        log.contains("shards not complete: 2") && log.contains("sbatch --array=K"),
        "{log}"
    );
    assert!(sbatch_and_wait(&["--array=2"], &p("job/array.sbatch")));
    assert!(sbatch_and_wait(&[], &p("job/merge.sbatch")));
    assert_eq!(
        fs::read(p("full.csv")).unwrap(),
        fs::read(p("merged.csv")).unwrap()
    );
}

fn ok(args: &[&str]) {
    cradle().args(args).assert().success();
}

/// A 5-ball mass × gap map, optionally with a third axis and a `[refine]`.
fn refine_sweep(dir: &Path, name: &str, axes: &str, refine: &str) -> PathBuf {
    let p = dir.join(name);
    fs::write(
        &p,
        format!("[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n{axes}\n{refine}\n"),
    )
    .unwrap();
    p
}

const MAP_AXES: &str = "[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.0064, 0.64, 97]\n[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 2e-5, 80]\n";

/// The rows of a CSV after its header, keyed by id.
fn rows_by_id(p: &Path) -> Vec<(u64, String)> {
    fs::read_to_string(p)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            (
                l.split(',').next().unwrap().parse().unwrap(),
                format!("{l}\n"),
            )
        })
        .collect()
}

#[test]
fn refinement_computes_few_scenes_with_the_full_grids_bytes_and_fills_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let full = refine_sweep(d, "full.toml", MAP_AXES, "");
    let refined = refine_sweep(
        d,
        "ref.toml",
        MAP_AXES,
        "[refine]\ncolumn = \"ejected\"\nstride = 4\n",
    );
    let (full_csv, ref_csv, filled) = (d.join("full.csv"), d.join("ref.csv"), d.join("filled.csv"));
    sweep(&[
        full.to_str().unwrap(),
        "--out",
        full_csv.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    sweep(&[
        refined.to_str().unwrap(),
        "--out",
        ref_csv.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    let all = rows_by_id(&full_csv);
    let part = rows_by_id(&ref_csv);
    // Exactly the computed scenes, once each, in id order, with the full grid's bytes.
    assert!(part.windows(2).all(|w| w[0].0 < w[1].0));
    for (id, row) in &part {
        assert_eq!(&all[*id as usize].1, row, "id {id}");
    }
    let head = |p: &Path| {
        fs::read_to_string(p)
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .to_string()
    };
    assert_eq!(head(&ref_csv), head(&full_csv));
    assert!(
        part.len() < all.len() / 3,
        "{} of {}",
        part.len(),
        all.len()
    );
    // The sidecar counts each level; the levels add up to the rows.
    let sc: serde_json::Value =
        serde_json::from_slice(&fs::read(d.join("ref.csv.json")).unwrap()).unwrap();
    let levels = sc["refine"]["levels"].as_array().unwrap();
    assert_eq!(levels[0]["stride"], 4);
    assert_eq!(levels.last().unwrap()["stride"], 1);
    let sum: u64 = levels.iter().map(|l| l["scenes"].as_u64().unwrap()).sum();
    assert_eq!(sum as usize, part.len());
    assert_eq!(
        sc["scenes_ok"].as_u64().unwrap() + sc["scenes_not_ok"].as_u64().unwrap(),
        sum
    );
    // Filled, the map matches the full grid's `ejected` almost everywhere.
    ok(&[
        "fill",
        ref_csv.to_str().unwrap(),
        "--out",
        filled.to_str().unwrap(),
    ]);
    let f = rows_by_id(&filled);
    assert_eq!(f.len(), all.len());
    let col = head(&full_csv)
        .split(',')
        .position(|c| c == "ejected")
        .unwrap();
    let field = |r: &str| r.trim_end().split(',').nth(col).unwrap().to_string();
    let wrong = f
        .iter()
        .zip(&all)
        .filter(|(a, b)| field(&a.1) != field(&b.1))
        .count();
    assert!(
        wrong * 1000 <= all.len(),
        "{wrong} of {} cells wrong",
        all.len()
    );
    for ((ia, a), (ib, b)) in f.iter().zip(&all) {
        assert_eq!(ia, ib);
        // Axis values are each cell's own.
        assert_eq!(
            a.split(',').take(3).collect::<Vec<_>>(),
            b.split(',').take(3).collect::<Vec<_>>()
        );
    }
    // A disk that fills at the write of any level (one batch each here):
    // --resume finishes the same bytes.
    let want = fs::read(&ref_csv).unwrap();
    for k in [1, 2, 3] {
        let out = d.join(format!("ref{k}.csv"));
        let o = cradle()
            .args([
                "sweep",
                refined.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--backend",
                "cpu",
            ])
            .env("CRADLE_FAILPOINT", format!("append:{k}"))
            .output()
            .unwrap();
        assert_eq!(
            o.status.code(),
            Some(1),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!out.exists());
        sweep(&[
            refined.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--backend",
            "cpu",
            "--resume",
        ]);
        assert_eq!(fs::read(&out).unwrap(), want, "failpoint append:{k}");
    }
}

#[test]
fn refinement_in_three_axes_with_a_threshold_shards_parquet_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let axes = "[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.0064, 0.64, 33]\n[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 2e-5, 17]\n[[axis]]\nparam = \"velocity[0]\"\nvalues = [0.5, 1.0, 2.0]\n";
    let full = refine_sweep(d, "full.toml", axes, "");
    let refined = refine_sweep(
        d,
        "ref.toml",
        axes,
        "[refine]\ncolumn = \"energy_last\"\nthreshold = 0.05\nstride = 8\n",
    );
    let (full_csv, ref_csv) = (d.join("full.csv"), d.join("ref.csv"));
    sweep(&[
        full.to_str().unwrap(),
        "--out",
        full_csv.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    sweep(&[
        refined.to_str().unwrap(),
        "--out",
        ref_csv.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    let all = rows_by_id(&full_csv);
    let part = rows_by_id(&ref_csv);
    assert!(part.windows(2).all(|w| w[0].0 < w[1].0) && part.len() < all.len());
    for (id, row) in &part {
        assert_eq!(&all[*id as usize].1, row);
    }
    let refused = |args: &[&str], needle: &str| {
        let o = cradle().args(args).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(needle), "{e:?} lacks {needle:?}");
    };
    let r = refined.to_str().unwrap();
    let x = d.join("x.csv");
    let x = x.to_str().unwrap();
    // Shards of a refined sweep merge into the unsharded refined file.
    let mut parts = vec![];
    for k in 1..=3 {
        let part = d.join(format!("part{k}.csv"));
        sweep(&[
            r,
            "--out",
            part.to_str().unwrap(),
            "--backend",
            "cpu",
            "--shard",
            &format!("{k}/3"),
        ]);
        parts.push(part.to_str().unwrap().to_string());
    }
    let merged = d.join("merged.csv");
    let mut args = vec!["merge".to_string()];
    args.extend(parts);
    args.extend(["--out".into(), merged.to_str().unwrap().into()]);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(fs::read(&merged).unwrap(), fs::read(&ref_csv).unwrap());
    // As Parquet: the same rows, typed.
    let pq = d.join("ref.parquet");
    sweep(&[r, "--out", pq.to_str().unwrap(), "--backend", "cpu"]);
    let (header, rows) = hertz_cradle::output::parquet_file::read_text(&pq).unwrap();
    let text = fs::read_to_string(&ref_csv).unwrap();
    assert_eq!(header.join(","), text.lines().next().unwrap());
    let csv_rows: Vec<String> = text.lines().skip(1).map(str::to_string).collect();
    assert_eq!(
        rows.iter().map(|r| r.join(",")).collect::<Vec<_>>(),
        csv_rows
    );
    for (refine, needle) in [
        ("[refine]\ncolumn = \"v_4\"\n", "needs `threshold`"),
        (
            "[refine]\ncolumn = \"ejectd\"\n",
            "a column of this sweep's table",
        ),
        ("[refine]\ncolumn = \"gap\"\n", "an outcome column"),
        (
            "[refine]\ncolumn = \"ejected\"\nstride = 3\n",
            "a power of two",
        ),
        ("[refine]\ncolum = \"ejected\"\n", "colum"),
        (
            "[refine]\ncolumn = \"status\"\nthreshold = 0.5\n",
            "a text column",
        ),
    ] {
        let p = refine_sweep(d, "bad.toml", axes, refine);
        refused(&["sweep", p.to_str().unwrap(), "--out", x], needle);
    }
}

#[test]
fn a_point_list_runs_one_scene_per_row_and_bad_tables_say_where() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = "[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n";
    fs::write(
        d.join("params.csv"),
        "gap,mass[2],glue\n0,0.01,----\n1e-5,0.5,-=--\n2e-5,0.064,--==\n",
    )
    .unwrap();
    let sw = d.join("p.toml");
    fs::write(&sw, format!("{scene}[points]\nfile = \"params.csv\"\n")).unwrap();
    let out = d.join("p.csv");
    sweep(&[
        sw.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    let text = fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("id,gap,mass[2],glue,status,v_0"));
    assert_eq!(lines.len(), 4);
    assert!(lines[2].starts_with("1,1e-5,0.5,-=--,ok,"), "{}", lines[2]);
    // Row 1 equals the same scene in a one-scene grid sweep (same bytes after the axes).
    let g = d.join("g.toml");
    fs::write(
        &g,
        format!("{scene}[[axis]]\nparam = \"gap\"\nvalues = [1e-5]\n[[axis]]\nparam = \"mass[2]\"\nvalues = [0.5]\n[[axis]]\nparam = \"glue\"\nvalues = [\"-=--\"]\n"),
    )
    .unwrap();
    let gout = d.join("g.csv");
    sweep(&[
        g.to_str().unwrap(),
        "--out",
        gout.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    let grow = fs::read_to_string(&gout)
        .unwrap()
        .lines()
        .nth(1)
        .unwrap()
        .to_string();
    assert_eq!(&lines[2][1..], &grow[1..]);
    for (table, needle) in [
        (
            "gap,mass[2]\n0,abc\n",
            "p.csv:2: `mass[2]` = \"abc\": a finite number",
        ),
        ("gap,mas[2]\n0,0.1\n", "did you mean `mass`"),
        ("gap,mass[2]\n0,0.1\n0,-2\n", "p.csv:3: `mass[2]` = -2"),
        ("gap,mass[2]\n", "at least one row"),
        ("", "a header naming the params"),
        ("gap,mass[2]\n0\n", "2 fields"),
        ("gap,mass[9]\n0,0.1\n", "an index in 0 ..= 4"),
        ("balls,gap\n2.5,0\n", "whole number"),
        ("mass,mass[1]\n1,1\n", "one column"),
        // A row that turns the cradle into a chain (a taper: it ran 5-ball
        // "chains" on the cradle engine) is refused.
        (
            "gap,taper.ratio\n0,0.1\n",
            "p.csv:2: `taper.ratio` = 0.1: a scene like the base scene",
        ),
    ] {
        fs::write(d.join("bad.p.csv"), table).unwrap();
        let b = d.join("b.toml");
        fs::write(&b, format!("{scene}[points]\nfile = \"bad.p.csv\"\n")).unwrap();
        let o = cradle()
            .args([
                "sweep",
                b.to_str().unwrap(),
                "--out",
                d.join("x.csv").to_str().unwrap(),
            ])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{table:?}: {e}");
        assert!(e.contains(needle), "{table:?}: {e:?} lacks {needle:?}");
    }
    // 65 balls on a launched cradle's base made a chain that the cradle
    // engine ran and panicked on (exit 101): refused like an axis value.
    fs::write(
        d.join("launch.toml"),
        "balls = 5\n[launch]\nballs = 1\nvelocity = 1.0\n",
    )
    .unwrap();
    fs::write(d.join("n.p.csv"), "balls,gap\n5,0\n65,0\n").unwrap();
    let b = d.join("n.toml");
    fs::write(
        &b,
        "scene = \"launch.toml\"\n[points]\nfile = \"n.p.csv\"\n",
    )
    .unwrap();
    let o = cradle()
        .args([
            "sweep",
            b.to_str().unwrap(),
            "--out",
            d.join("n.csv").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("n.p.csv:3: `balls` = 65: a scene like the base scene"),
        "{e}"
    );
}

#[test]
fn sampling_designs_are_seeded_sharded_and_keep_their_properties() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 500;
    let spec = |design: &str, seed: u64| {
        format!("[scene]\nballs = 5\n[scene.launch]\nballs = 1\nvelocity = 1.0\n[sample]\ndesign = \"{design}\"\npoints = {n}\nseed = {seed}\n[[axis]]\nparam = \"mass[2]\"\nrange = [0.0064, 0.64]\nscale = \"log\"\n[[axis]]\nparam = \"gap\"\nrange = [0.0, 2e-5]\n[[axis]]\nparam = \"launch.balls\"\nrange = [1, 3]\n")
    };
    let run = |name: &str, text: String, extra: &[&str]| -> String {
        let p = d.join(format!("{name}.toml"));
        fs::write(&p, text).unwrap();
        let out = d.join(format!("{name}.csv"));
        let mut a = vec![
            p.to_str().unwrap().to_string(),
            "--out".into(),
            out.to_str().unwrap().into(),
        ];
        a.extend([
            "--backend".into(),
            "cpu".into(),
            "--model".into(),
            "hard-sphere".into(),
        ]);
        a.extend(extra.iter().map(|s| s.to_string()));
        sweep(&a.iter().map(String::as_str).collect::<Vec<_>>());
        fs::read_to_string(out).unwrap()
    };
    let cols = |text: &str, k: usize| -> Vec<f64> {
        text.lines()
            .skip(1)
            .map(|l| l.split(',').nth(k).unwrap().parse().unwrap())
            .collect()
    };
    let lhs = run("lhs", spec("lhs", 4), &[]);
    // Every stratum of every axis once: mass (log scale), gap (linear).
    let (lo, hi) = (0.0064f64.ln(), 0.64f64.ln());
    for (k, to_unit) in [
        (
            1,
            Box::new(move |x: f64| (x.ln() - lo) / (hi - lo)) as Box<dyn Fn(f64) -> f64>,
        ),
        (2, Box::new(|x: f64| x / 2e-5)),
    ] {
        let mut strata: Vec<usize> = cols(&lhs, k)
            .iter()
            .map(|&x| ((to_unit(x) * n as f64).floor() as usize).min(n - 1))
            .collect();
        strata.sort();
        assert_eq!(strata, (0..n).collect::<Vec<_>>(), "axis {k}");
    }
    // Integer axes draw integers in their range, all of them.
    let balls = cols(&lhs, 3);
    assert!(balls.iter().all(|b| [1.0, 2.0, 3.0].contains(b)));
    assert!([1.0, 2.0, 3.0].iter().all(|b| balls.contains(b)));
    // Same seed, same bytes; another seed, other points.
    assert_eq!(run("lhs2", spec("lhs", 4), &[]), lhs);
    assert_ne!(run("lhs3", spec("lhs", 5), &[]), lhs);
    // Shards draw their own slice: merged, the unsharded file.
    let sob = run("sobol", spec("sobol", 0), &[]);
    assert!(
        sob.lines().nth(1).unwrap().starts_with("0,0.0064,0,1,"),
        "point 0 is the origin"
    );
    for k in 1..=2 {
        run(
            &format!("s{k}"),
            spec("sobol", 0),
            &["--shard", &format!("{k}/2")],
        );
    }
    let m = d.join("m.csv");
    ok(&[
        "merge",
        d.join("s1.csv").to_str().unwrap(),
        d.join("s2.csv").to_str().unwrap(),
        "--out",
        m.to_str().unwrap(),
    ]);
    assert_eq!(fs::read_to_string(m).unwrap(), sob);
    let rnd = run("random", spec("random", 1), &[]);
    assert_eq!(rnd.lines().count(), n + 1);
}

/// The typed API (what the CLI and the Python module are clients of): the
/// rows a sweep hands to `on_row` are the table's rows — same ids in the
/// same order, the same sweep values, outcomes whose text is the CSV's —
/// progress ends at the total, and the CLI writes the same bytes.
#[test]
fn typed_api_rows_are_the_tables_rows() {
    use hertz_cradle::backend::BackendChoice;
    use hertz_cradle::output::row::Cell;
    use hertz_cradle::{Hooks, Progress, SweepRequest, SweepRow, SweepSettings};
    use std::sync::{Arc, Mutex};
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("api.csv");
    let settings = SweepSettings {
        backend: BackendChoice::Cpu,
        ..SweepSettings::default()
    };
    let req = SweepRequest::from_toml("small", SMALL, ".", &out, &settings).unwrap();
    let rows: Arc<Mutex<Vec<SweepRow>>> = Arc::default();
    let last: Arc<Mutex<Option<Progress>>> = Arc::default();
    let (r2, l2) = (rows.clone(), last.clone());
    let s = req
        .run(Hooks {
            on_row: Some(Arc::new(move |r| r2.lock().unwrap().push(r.clone()))),
            on_progress: Some(Arc::new(move |p| *l2.lock().unwrap() = Some(p))),
            ..Hooks::default()
        })
        .unwrap();
    assert_eq!((s.scenes, s.ok), (12, 12));
    assert_eq!(
        *last.lock().unwrap(),
        Some(Progress {
            done: 12,
            total: 12
        })
    );
    let text = fs::read_to_string(&out).unwrap();
    let rows = rows.lock().unwrap();
    let lines: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), lines.len());
    for (r, line) in rows.iter().zip(&lines) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[0], r.id.to_string());
        let Cell::Num(gap) = r.params[1] else {
            panic!("{:?}", r.params)
        };
        assert_eq!(f[2].parse::<f64>().unwrap(), gap);
        assert_eq!(f[3], r.outcome.status().name());
        let o = r.outcome.cradle().expect("a cradle's row");
        assert_eq!(f[4].parse::<f64>().unwrap(), o.v[0], "{line}");
    }
    // The CLI on the same sweep: the same bytes.
    let file = d.path().join("small.toml");
    fs::write(&file, SMALL).unwrap();
    let cli_out = d.path().join("cli.csv");
    cradle()
        .args(["sweep", file.to_str().unwrap(), "--backend", "cpu", "--out"])
        .arg(&cli_out)
        .assert()
        .success();
    assert_eq!(fs::read(&cli_out).unwrap(), text.as_bytes());
}

/// Typed errors: bad settings are `Error::Input` holding the `InputError`
/// with the CLI's message, before anything is written; a cancelled run is
/// `Error::Interrupted` and leaves its partial file, which `resume` finishes
/// into the uninterrupted run's bytes.
#[test]
fn typed_api_errors_and_cancellation() {
    use hertz_cradle::backend::BackendChoice;
    use hertz_cradle::{Error, Hooks, SolverSettings, SweepRequest, SweepSettings};
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("c.csv");
    let bad = SweepSettings {
        solver: SolverSettings {
            tolerance: Some(2.0),
            ..SolverSettings::default()
        },
        ..SweepSettings::default()
    };
    let e = SweepRequest::from_toml("small", SMALL, ".", &out, &bad).unwrap_err();
    assert!(e.to_string().starts_with("--tolerance 2:"), "{e}");
    let e = Error::from(e);
    assert!(e.input_error().is_some());
    assert!(!out.exists());

    let settings = SweepSettings {
        backend: BackendChoice::Cpu,
        ..SweepSettings::default()
    };
    let req = SweepRequest::from_toml("small", SMALL, ".", &out, &settings).unwrap();
    let e = req
        .run(Hooks {
            cancel: Some(Arc::new(AtomicBool::new(true))),
            ..Hooks::default()
        })
        .unwrap_err();
    assert!(matches!(e, Error::Interrupted), "{e}");
    assert!(!out.exists());
    assert!(d.path().join("c.csv.partial").exists());
    let resumed = SweepSettings {
        resume: true,
        ..settings.clone()
    };
    SweepRequest::from_toml("small", SMALL, ".", &out, &resumed)
        .unwrap()
        .run(Hooks::default())
        .unwrap();
    let fresh = d.path().join("fresh.csv");
    SweepRequest::from_toml("small", SMALL, ".", &fresh, &settings)
        .unwrap()
        .run(Hooks::default())
        .unwrap();
    assert_eq!(fs::read(&out).unwrap(), fs::read(&fresh).unwrap());
}

/// A sweep of granular chains (docs/SPEC.md §9): dotted axis names, the
/// chain's columns, every row the chain engine's run of that scene.
const CHAINS: &str = r#"
[scene]
balls = 80
radius = 0.005
[scene.walls]
left = true
right = true
precompression = 1.0
[scene.pattern]
radius = [0.005, 0.004]
[scene.pulse]
bead = 0
force = 0.5
duration = 2e-5
[scene.probes]
beads = [20, 60]
[scene.solver]
tolerance = 1e-4

[[axis]]
param = "walls.precompression"
values = [0.5, 2.0]

[[axis]]
param = "pattern.radius[1]"
values = [0.003, 0.004]
"#;

#[test]
fn a_sweep_of_chains_writes_each_chains_own_run() {
    use hertz_cradle::backend::BackendChoice;
    use hertz_cradle::engine::granular::{self, Beads};
    use hertz_cradle::engine::{Overrides, Solver};
    use hertz_cradle::output::chain_row;
    use hertz_cradle::{Hooks, SweepRequest, SweepRow, SweepSettings};
    use std::sync::{Arc, Mutex};
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("chains.csv");
    let settings = SweepSettings {
        backend: BackendChoice::Cpu,
        ..SweepSettings::default()
    };
    let req = SweepRequest::from_toml("chains", CHAINS, ".", &out, &settings).unwrap();
    let rows: Arc<Mutex<Vec<SweepRow>>> = Arc::default();
    let r2 = rows.clone();
    let s = req
        .run(Hooks {
            on_row: Some(Arc::new(move |r| r2.lock().unwrap().push(r.clone()))),
            ..Hooks::default()
        })
        .unwrap();
    assert_eq!((s.scenes, s.ok), (4, 4));
    let text = fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // Above 64 beads the final velocities are the probes' only.
    assert_eq!(
        header[..13],
        [
            "id",
            "walls.precompression",
            "pattern.radius[1]",
            "status",
            "arrival_20",
            "peak_v_20",
            "peak_f_20",
            "arrival_60",
            "peak_v_60",
            "peak_f_60",
            "v_20",
            "v_60",
            "pulse_speed"
        ]
    );
    let col = |f: &[&str], name: &str| -> f64 {
        f[header.iter().position(|h| *h == name).unwrap()]
            .parse()
            .unwrap()
    };
    let rows = rows.lock().unwrap();
    let mut speeds = vec![];
    for (line, typed) in lines.zip(rows.iter()) {
        let f: Vec<&str> = line.split(',').collect();
        let id: u64 = f[0].parse().unwrap();
        assert_eq!(typed.id, id);
        // The row is the chain engine's run of scene `id` under the error
        // control (docs/SPEC.md §9), field for field.
        let scene = req.sweep.scene(id).unwrap();
        let beads = Beads::from_scene(&scene);
        let solver = Solver::resolve(&scene, &Overrides::default()).unwrap();
        let job = hertz_cradle::backend::ChainJob {
            beads: beads.clone(),
            plan: granular::plan(&beads, &solver, None),
        };
        let o = hertz_cradle::backend::run_chains_controlled(
            &hertz_cradle::backend::cpu::Cpu,
            1,
            &|_| Ok(Some(job.clone())),
        )
        .unwrap()
        .remove(0);
        assert!(o.error_estimate.is_finite());
        assert_eq!(f[3..], chain_row::fields(&beads, &o)[..], "row {id}");
        assert_eq!(typed.outcome.chain().unwrap().steps, o.steps);
        // The axes took effect: the walls carry the precompression swept,
        // the pulse passes both probes, the dimer's small bead changes it.
        let f0 = [0.5, 2.0][id as usize / 2];
        assert_eq!(col(&f, "walls.precompression"), f0);
        assert_eq!(beads.radius[1], [0.003, 0.004][id as usize % 2]);
        assert!(col(&f, "wall_left_peak_force") > f0, "{line}");
        assert!(col(&f, "arrival_60") > col(&f, "arrival_20"), "{line}");
        speeds.push(col(&f, "pulse_speed"));
    }
    assert_eq!(speeds.len(), 4);
    // Sound travels faster under more precompression.
    assert!(speeds[2] > speeds[0] && speeds[3] > speeds[1], "{speeds:?}");
    // The CLI, one thread: the same bytes; Parquet: the same rows.
    let file = d.path().join("chains.toml");
    fs::write(&file, CHAINS).unwrap();
    let cli_out = d.path().join("cli.csv");
    cradle()
        .args(["sweep", file.to_str().unwrap(), "--threads", "1", "--out"])
        .arg(&cli_out)
        .assert()
        .success();
    assert_eq!(fs::read_to_string(&cli_out).unwrap(), text);
    let pq = d.path().join("chains.parquet");
    cradle()
        .args(["sweep", file.to_str().unwrap(), "--out"])
        .arg(&pq)
        .assert()
        .success();
    let (h, pq_rows) = hertz_cradle::output::parquet_file::read_text(&pq).unwrap();
    assert_eq!(h.join(","), text.lines().next().unwrap());
    for (r, line) in pq_rows.iter().zip(text.lines().skip(1)) {
        assert_eq!(r.join(","), line);
    }
}

#[test]
fn chain_sweeps_refuse_what_they_cannot_run() {
    let chain_axis = |param: &str, values: &str| {
        CHAINS.split("[[axis]]").next().unwrap().to_string()
            + &format!("[[axis]]\nparam = \"{param}\"\nvalues = {values}\n")
    };
    // A pattern index outside the period, an array the pattern lacks.
    let e = sweep_text(&chain_axis("pattern.radius[2]", "[0.003]")).unwrap_err();
    assert!(
        e.contains("pattern.radius[2]") && e.contains("0 ..= 1"),
        "{e}"
    );
    let e = sweep_text(&chain_axis("pattern.mass[0]", "[0.003]")).unwrap_err();
    assert!(e.contains("[pattern] table (it has none)"), "{e}");
    // An axis of a key the pattern replaces would label values never used.
    let text = chain_axis("radius", "[0.004]")
        + "[[axis]]\nparam = \"pattern.radius[0]\"\nvalues = [0.003]\n";
    let e = sweep_text(&text).unwrap_err();
    assert!(e.contains("pattern.radius[0]"), "{e}");
    // A value that turns a chain into a cradle, or a cradle into a chain.
    let e = sweep_text(&chain_axis("balls", "[62, 80]")).map(|s| s.total);
    assert_eq!(
        e,
        Ok(2),
        "a chain of 62 beads with [walls] is still a chain"
    );
    let cradle = "[scene]\nballs = 5\nvelocity = [1.0, 0, 0, 0, 0]\n[[axis]]\nparam = \"taper.ratio\"\nvalues = [0.1]\n";
    let e = sweep_text(cradle).unwrap_err();
    assert!(e.contains("all cradles or all granular chains"), "{e}");
    // Bad values name the key and what is allowed.
    let e = sweep_text(&chain_axis("taper.ratio", "[1.5]")).unwrap_err();
    assert!(e.contains("taper.ratio") && e.contains("1.5"), "{e}");
}

/// A backend that takes several calls at once (a GPU's calls and the
/// batches packed beside them) is given that many, however large its
/// batches: the lanes' bound on running ahead of the writer is never below
/// it (at batches of 65,536 scenes the rows-ahead bound alone allows 3).
#[test]
fn a_backend_gets_as_many_calls_at_once_as_it_takes() {
    use hertz_cradle::backend::{cpu::Cpu, Backend, Job};
    use hertz_cradle::engine::Outcome;
    use hertz_cradle::sweep::{run::run, session::Options};
    use std::sync::{Condvar, Mutex};
    const CALLS: usize = 4;
    /// The CPU, in batches of 65,536, taking CALLS at once; each call
    /// waits (2 s at most) until CALLS have been in at once, so that the
    /// most seen is what the sweep allowed, not what the timing gave.
    struct Wide {
        inside: Mutex<(usize, usize)>, // (now, most)
        cv: Condvar,
    }
    impl Backend for Wide {
        fn name(&self) -> &'static str {
            "cpu"
        }
        fn adapter(&self) -> String {
            "a test's".into()
        }
        fn batch_size(&self) -> u64 {
            65_536
        }
        fn max_concurrent_runs(&self) -> usize {
            CALLS
        }
        fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>> {
            let mut g = self.inside.lock().unwrap();
            g.0 += 1;
            g.1 = g.1.max(g.0);
            self.cv.notify_all();
            let t0 = std::time::Instant::now();
            while g.1 < CALLS && t0.elapsed() < Duration::from_secs(2) {
                g = self
                    .cv
                    .wait_timeout(g, Duration::from_millis(50))
                    .unwrap()
                    .0;
            }
            drop(g);
            let out = Cpu.run(jobs);
            self.inside.lock().unwrap().0 -= 1;
            out
        }
    }
    // 266,240 two-ball cradles: four full batches and a short one.
    let sweep = sweep_text(
        "[scene]\nballs = 2\nvelocity = [1.0, 0.0]\n[[axis]]\nparam = \"mass[1]\"\nlinspace = [0.01, 0.1, 512]\n[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 1e-5, 520]\n",
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = Options::new(dir.path().join("two.csv"));
    let wide = Wide {
        inside: Mutex::new((0, 0)),
        cv: Condvar::new(),
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(CALLS + 2)
        .build()
        .unwrap()
        .install(|| run(&sweep, &opts, &wide))
        .unwrap();
    assert_eq!(wide.inside.lock().unwrap().1, CALLS);
    let rows = fs::read_to_string(&opts.out).unwrap().lines().count();
    assert_eq!(rows, 266_240 + 1);
}
