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
