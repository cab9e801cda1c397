//! Fault injection: what a sweep does when the disk fills, when it is killed,
//! when two runs write one output, when an output path is hostile, when
//! resume and merge meet parts that do not belong together, and when a
//! request is absurd. Every case asserts that nothing already written is lost
//! and that whatever is claimed complete is correct (docs/GUIDE.md, "Guarantees").

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command as Std, Output};
use std::time::{Duration, Instant};

use assert_cmd::Command;

fn cradle() -> Command {
    Command::cargo_bin("cradle").unwrap()
}

/// A sweep of `n_mass` × `n_gap` five-ball scenes in `dir` (scene in a file).
fn write_sweep(dir: &Path, n_mass: usize, n_gap: usize) -> PathBuf {
    fs::write(
        dir.join("scene.toml"),
        "balls = 5\nvelocity = [1.0, 0, 0, 0, 0]\n",
    )
    .unwrap();
    let p = dir.join("sweep.toml");
    fs::write(
        &p,
        format!("scene = \"scene.toml\"\n[[axis]]\nparam = \"mass[2]\"\nlogspace = [0.01, 0.5, {n_mass}]\n[[axis]]\nparam = \"gap\"\nlinspace = [0.0, 2e-5, {n_gap}]\n"),
    )
    .unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run<A: AsRef<std::ffi::OsStr>>(args: &[A]) -> Output {
    cradle().args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Expect exit 2 (bad input) with `needle` in the message.
fn refused<A: AsRef<std::ffi::OsStr> + std::fmt::Debug>(args: &[A], needle: &str) -> String {
    let o = run(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(e.contains(needle), "{args:?}: {e:?} lacks {needle:?}");
    e
}

/// `cradle sweep SWEEP --out OUT --backend cpu EXTRA...`
fn on_cpu<'a>(sw: &'a Path, out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec!["sweep", s(sw), "--out", s(out), "--backend", "cpu"];
    a.extend_from_slice(extra);
    a
}

/// A sidecar's JSON.
fn sidecar(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&fs::read(path).unwrap()).unwrap()
}

fn ok(args: &[&str]) {
    let o = run(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
}

/// A small deterministic generator for the "random" points of a test.
fn points(seed: u64, n: usize, lo: u64, hi: u64) -> Vec<u64> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            lo + x % (hi - lo)
        })
        .collect()
}

#[test]
fn hostile_output_paths_are_refused_before_any_work_and_nothing_is_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 3, 3);
    let sweep_bytes = fs::read(&sw).unwrap();
    let scene = d.join("scene.toml");
    let scene_bytes = fs::read(&scene).unwrap();
    // The sweep file and the scene file it names.
    refused(&["sweep", s(&sw), "--out", s(&sw)], "is an input");
    refused(&["sweep", s(&sw), "--out", s(&scene)], "is an input");
    // A name whose companion (`.json`) would be an input.
    let sweep_as_out = d.join("sweep");
    fs::rename(&sw, d.join("sweep.json")).unwrap();
    let sw2 = d.join("sweep.json");
    refused(
        &["sweep", s(&sw2), "--out", s(&sweep_as_out)],
        "is an input",
    );
    fs::rename(&sw2, &sw).unwrap();
    // A directory, found before the sweep runs.
    fs::create_dir(d.join("adir")).unwrap();
    refused(
        &["sweep", s(&sw), "--out", s(&d.join("adir"))],
        "is a directory",
    );
    refused(
        &["sweep", s(&sw), "--out", s(&d.join("no/such/dir/o.csv"))],
        "does not exist",
    );
    // A FIFO: refused, and still a FIFO afterwards.
    let fifo = d.join("fifo.csv");
    if Std::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        refused(&["sweep", s(&sw), "--out", s(&fifo)], "FIFO");
        use std::os::unix::fs::FileTypeExt;
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    }
    // A device node (/dev/null itself is only ever checked, never written to
    // by a test): refused by the same rule.
    refused(&["sweep", s(&sw), "--out", "/dev/null"], "device node");
    let null = d.join("null");
    if Std::new("mknod")
        .args([s(&null), "c", "1", "3"])
        .status()
        .is_ok_and(|s| s.success())
    {
        refused(&["sweep", s(&sw), "--out", s(&null)], "device node");
        use std::os::unix::fs::FileTypeExt;
        assert!(fs::symlink_metadata(&null)
            .unwrap()
            .file_type()
            .is_char_device());
    }
    // A symlink to the sweep file: refused; a symlink to a new name: written
    // through, the link kept.
    let link_in = d.join("link_in.csv");
    std::os::unix::fs::symlink(&sw, &link_in).unwrap();
    refused(&["sweep", s(&sw), "--out", s(&link_in)], "is an input");
    let link = d.join("link.csv");
    std::os::unix::fs::symlink("target.csv", &link).unwrap();
    ok(&on_cpu(&sw, &link, &[]));
    assert!(fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let target = fs::read_to_string(d.join("target.csv")).unwrap();
    assert_eq!(target.lines().count(), 10, "{target}");
    assert!(d.join("target.csv.json").exists());
    // Inputs untouched by all of it.
    assert_eq!(fs::read(&sw).unwrap(), sweep_bytes);
    assert_eq!(fs::read(&scene).unwrap(), scene_bytes);
    // The same rule guards merge, trace and plot outputs.
    refused(&["run", s(&scene), "--trace", s(&scene)], "is an input");
    refused(
        &[
            "merge",
            s(&d.join("target.csv")),
            "--out",
            s(&d.join("target.csv")),
        ],
        "is an input",
    );
    refused(
        &[
            "plot",
            s(&d.join("target.csv")),
            "--x",
            "gap",
            "--y",
            "mass[2]",
            "--z",
            "ejected",
            "--out",
            s(&d.join("adir")),
        ],
        "is a directory",
    );
    assert_eq!(fs::read(&scene).unwrap(), scene_bytes);
}

#[test]
fn a_second_writer_is_refused_while_the_first_finishes_intact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 40, 1000); // 40,000 scenes: seconds on one thread
    let (out, reference) = (d.join("o.csv"), d.join("ref.csv"));
    ok(&on_cpu(&sw, &reference, &[]));
    let mut first = Std::new(assert_cmd::cargo::cargo_bin("cradle"))
        .args([
            "sweep",
            s(&sw),
            "--out",
            s(&out),
            "--backend",
            "cpu",
            "--threads",
            "1",
        ])
        .spawn()
        .unwrap();
    let partial = d.join("o.csv.partial");
    let t0 = Instant::now();
    while fs::metadata(&partial).map_or(0, |m| m.len()) == 0
        && t0.elapsed() < Duration::from_secs(60)
    {
        std::thread::sleep(Duration::from_millis(5));
    }
    let pid = format!("pid {}", first.id());
    for extra in [&[][..], &["--resume"][..], &["--shard", "1/2"][..]] {
        let mut args = vec!["sweep", s(&sw), "--out", s(&out), "--backend", "cpu"];
        args.extend_from_slice(extra);
        let e = refused(&args, "being written by another cradle");
        assert!(e.contains(&pid), "{e}");
    }
    // merge into the same output is refused too
    refused(&["merge", s(&reference), "--out", s(&out)], &pid);
    assert!(first.wait().unwrap().success());
    assert_eq!(fs::read(&out).unwrap(), fs::read(&reference).unwrap());
    assert!(!d.join("o.csv.lock").exists());
}

#[test]
fn disk_full_at_random_points_loses_nothing_and_resume_completes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 10, 1000); // 10,000 scenes: 5 batches of rows
    let reference = d.join("ref.csv");
    ok(&on_cpu(&sw, &reference, &[]));
    let want = fs::read(&reference).unwrap();
    for (i, k) in points(7, 3, 1, 6).into_iter().enumerate() {
        let out = d.join(format!("o{i}.csv"));
        let o = cradle()
            .args(["sweep", s(&sw), "--out", s(&out), "--backend", "cpu"])
            .env("CRADLE_FAILPOINT", format!("append:{k}"))
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        let name = format!("o{i}.csv.partial");
        assert!(
            e.contains("No space left on device") && e.contains(&name),
            "{e}"
        );
        assert!(!out.exists(), "a failed run must not look complete");
        // What reached the file is a prefix of the right answer.
        let part = fs::read(d.join(format!("o{i}.csv.partial"))).unwrap();
        assert!(want.starts_with(&part) && part.len() < want.len());
        ok(&on_cpu(&sw, &out, &["--resume"]));
        assert_eq!(fs::read(&out).unwrap(), want, "failpoint append:{k}");
    }
    // The sidecar cannot be written: no CSV is published, no torn sidecar.
    let out = d.join("side.csv");
    let o = cradle()
        .args(["sweep", s(&sw), "--out", s(&out), "--backend", "cpu"])
        .env("CRADLE_FAILPOINT", "sidecar:1")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!out.exists() && !d.join("side.csv.json").exists());
    ok(&on_cpu(&sw, &out, &["--resume"]));
    assert_eq!(fs::read(&out).unwrap(), want);
    let meta = sidecar(&d.join("side.csv.json"));
    assert_eq!(
        meta["scenes_ok"].as_u64().unwrap() + meta["scenes_not_ok"].as_u64().unwrap(),
        10_000
    );
}

/// `cradle sweep SW --out OUT --backend cpu --threads 1`, sent `signal`
/// (`-INT`, `-TERM`) once `OUT.partial` holds at least `bytes`: its output.
fn interrupted_sweep(sw: &Path, out: &Path, signal: &str, bytes: u64) -> Output {
    let partial = PathBuf::from(format!("{}.partial", out.display()));
    let child = Std::new(assert_cmd::cargo::cargo_bin("cradle"))
        .args(["sweep", s(sw), "--out", s(out), "--backend", "cpu"])
        .args(["--threads", "1"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while fs::metadata(&partial).map_or(true, |m| m.len() < bytes)
        && t0.elapsed() < Duration::from_secs(60)
    {
        std::thread::sleep(Duration::from_millis(2));
    }
    let killed = Std::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    child.wait_with_output().unwrap()
}

/// Ctrl-C (SIGINT) during a sweep: the rows in hand are written, the run
/// says how many are kept and how to continue, exits 130 (docs/GUIDE.md's table),
/// and `--resume` completes the bytes of an uninterrupted run. SIGTERM the same.
#[test]
fn ctrl_c_keeps_the_rows_says_how_to_continue_and_resume_completes_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 200, 500); // 100,000 scenes: seconds on one thread
    let reference = d.join("ref.csv");
    ok(&on_cpu(&sw, &reference, &[]));
    let want = fs::read(&reference).unwrap();
    for signal in ["-INT", "-TERM"] {
        let out = d.join(format!("o{signal}.csv"));
        let partial = d.join(format!("o{signal}.csv.partial"));
        let o = interrupted_sweep(&sw, &out, signal, 100_000);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(130), "{signal}: {e}");
        assert!(!out.exists(), "an interrupted run must not look complete");
        let part = fs::read(&partial).unwrap();
        let rows = part.iter().filter(|&&b| b == b'\n').count() - 1;
        assert!(want.starts_with(&part) && rows > 0 && part.len() < want.len());
        assert!(
            e.contains(&format!(
                "interrupted: {rows} of 100000 scenes are kept in {}.partial; run the same command with --resume",
                out.display()
            )),
            "{signal}: {e}"
        );
        assert!(!d.join(format!("o{signal}.csv.lock")).exists());
        ok(&on_cpu(&sw, &out, &["--resume"]));
        assert_eq!(fs::read(&out).unwrap(), want, "{signal}");
    }
}

/// Ctrl-C while a batch is in hand stops that batch too, not only the next
/// ones: 40 64-ball cradles (~3 s on one thread) are one batch, so before,
/// an interrupt waited for all of them and still left the run partial. Now
/// the batch stops after the few scenes running (its rows are not kept: a
/// batch is written whole), the run says 0 of 40 are kept and exits 130, and
/// `--resume` completes the bytes of an uninterrupted run.
#[test]
fn ctrl_c_stops_the_batch_in_hand() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = d.join("heavy.toml");
    fs::write(
        &sw,
        "[scene]\nballs = 64\n[scene.launch]\nballs = 1\nvelocity = 1.0\n\
         [[axis]]\nparam = \"launch.velocity\"\nlinspace = [0.5, 1.5, 40]\n",
    )
    .unwrap();
    let out = d.join("h.csv");
    let o = interrupted_sweep(&sw, &out, "-INT", 0);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{e}");
    assert!(!out.exists(), "an interrupted run must not look complete");
    assert!(
        e.contains(&format!(
            "interrupted: 0 of 40 scenes are kept in {}.partial",
            out.display()
        )),
        "{e}"
    );
    ok(&on_cpu(&sw, &out, &["--resume"]));
    let reference = d.join("ref.csv");
    ok(&on_cpu(&sw, &reference, &[]));
    assert_eq!(fs::read(&out).unwrap(), fs::read(&reference).unwrap());
}

/// Ctrl-C during `run --trace FILE`: the trace being written and its lock
/// are removed (`FILE.tmp` was left behind), the run says so and exits 130.
#[test]
fn ctrl_c_during_a_trace_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("big.toml");
    fs::write(
        &scene,
        "balls = 1000\nradius = 0.005\n[launch]\nballs = 1\nvelocity = 0.1\n[record]\nstride = 1\nevery = 4e-6\n[stop]\nduration = 0.02\n",
    )
    .unwrap();
    let trace = d.join("t.csv");
    let tmp = d.join("t.csv.tmp");
    let child = Std::new(assert_cmd::cargo::cargo_bin("cradle"))
        .args(["run", s(&scene), "--trace", s(&trace)])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while fs::metadata(&tmp).map_or(0, |m| m.len()) == 0 && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(1));
    }
    Std::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let o = child.wait_with_output().unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{e}");
    assert!(e.contains("interrupted: no trace written"), "{e}");
    assert!(!tmp.exists() && !trace.exists() && !d.join("t.csv.lock").exists());
}

/// What ext4 can leave after a power cut: the last row torn, then a block
/// of zeros (with or without a newline in it). `--resume` keeps only whole
/// rows, says how many bytes it dropped, and completes the same bytes.
#[test]
fn resume_drops_a_torn_row_and_a_zero_filled_block_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 10, 1000); // 10,000 scenes: 5 batches of rows
    let reference = d.join("ref.csv");
    ok(&on_cpu(&sw, &reference, &[]));
    let want = fs::read(&reference).unwrap();
    for (i, tail) in [
        vec![0u8; 4096],
        [vec![0u8; 4000], b"\n".to_vec(), vec![0u8; 96]].concat(),
        [b"\n".to_vec(), vec![0u8; 4095]].concat(),
    ]
    .into_iter()
    .enumerate()
    {
        let out = d.join(format!("t{i}.csv"));
        let o = cradle()
            .args(["sweep", s(&sw), "--out", s(&out), "--backend", "cpu"])
            .env("CRADLE_FAILPOINT", "append:3")
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let partial = d.join(format!("t{i}.csv.partial"));
        let mut part = fs::read(&partial).unwrap();
        let whole = part.len();
        // Half of the next row, then the zeros.
        let next = want[whole..].iter().position(|&b| b == b'\n').unwrap();
        part.extend_from_slice(&want[whole..whole + next / 2]);
        part.extend_from_slice(&tail);
        fs::write(&partial, &part).unwrap();
        let o = run(&on_cpu(&sw, &out, &["--resume"]));
        let e = stderr(&o);
        assert!(o.status.success(), "{e}");
        let rows = want[..whole].iter().filter(|&&b| b == b'\n').count() - 1;
        assert!(
            e.contains(&format!(
                "resumed {} after {rows} whole rows; dropped the {} bytes after them",
                out.display(),
                part.len() - whole
            )),
            "{e}"
        );
        assert_eq!(fs::read(&out).unwrap(), want, "tail {i}");
    }
}

#[test]
fn kills_at_random_points_then_resume_give_the_same_bytes_and_a_whole_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 40, 200);
    let reference = d.join("ref.csv");
    ok(&on_cpu(&sw, &reference, &[]));
    let want = fs::read(&reference).unwrap();
    let out = d.join("o.csv");
    let partial = d.join("o.csv.partial");
    let mut kills = 0;
    // Kill -9 after a random number of bytes, three times, resuming each time.
    for at in points(11, 3, 1_000, 600_000) {
        let mut child = Std::new(assert_cmd::cargo::cargo_bin("cradle"))
            .args([
                "sweep",
                s(&sw),
                "--out",
                s(&out),
                "--backend",
                "cpu",
                "--threads",
                "1",
                "--resume",
            ])
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        while fs::metadata(&partial).map_or(0, |m| m.len()) < at
            && t0.elapsed() < Duration::from_secs(60)
            && child.try_wait().unwrap().is_none()
        {
            std::thread::sleep(Duration::from_millis(2));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        child.wait().unwrap();
        if out.exists() {
            break;
        }
        let part = fs::read(&partial).unwrap();
        assert!(want.starts_with(&part[..part.iter().rposition(|&b| b == b'\n').unwrap() + 1]));
    }
    assert!(kills > 0);
    ok(&on_cpu(&sw, &out, &["--resume"]));
    assert_eq!(fs::read(&out).unwrap(), want);
    let meta = sidecar(&d.join("o.csv.json"));
    let rows = meta["scenes_ok"].as_u64().unwrap() + meta["scenes_not_ok"].as_u64().unwrap();
    assert_eq!(
        rows, 8000,
        "the sidecar counts the whole file, not the last run"
    );
    let ref_meta = sidecar(&d.join("ref.csv.json"));
    assert_eq!(meta["scenes_ok"], ref_meta["scenes_ok"]);
    assert!(meta["wall_s"].as_f64().unwrap() >= meta["wall_s_this_run"].as_f64().unwrap());
}

#[test]
fn resume_and_merge_refuse_parts_that_do_not_belong_together() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 3, 4);
    let p = |n: &str| d.join(n);
    // `cradle merge PARTS... --out m.csv`, paths in the test's folder.
    let merge = |parts: &[&str]| -> Vec<String> {
        let mut a = vec!["merge".to_string()];
        a.extend(parts.iter().map(|n| p(n).display().to_string()));
        a.extend(["--out".to_string(), p("m.csv").display().to_string()]);
        a
    };
    // A complete output of another sweep is never taken as done by --resume.
    ok(&on_cpu(&sw, &p("a.csv"), &[]));
    let before = fs::read(p("a.csv")).unwrap();
    refused(
        &[
            "sweep",
            s(&sw),
            "--out",
            s(&p("a.csv")),
            "--backend",
            "cpu",
            "--resume",
            "--tolerance",
            "1e-8",
        ],
        "different sweep",
    );
    let other = d.join("other.toml");
    fs::write(
        &other,
        fs::read_to_string(&sw)
            .unwrap()
            .replace("0.5, 3]", "0.6, 3]"),
    )
    .unwrap();
    refused(
        &["sweep", s(&other), "--out", s(&p("a.csv")), "--resume"],
        "different sweep",
    );
    assert_eq!(fs::read(p("a.csv")).unwrap(), before);
    // The same sweep: already complete.
    let o = run(&[
        "sweep",
        s(&sw),
        "--out",
        s(&p("a.csv")),
        "--backend",
        "cpu",
        "--resume",
    ]);
    assert!(o.status.success() && stderr(&o).contains("already complete"));
    // Without its sidecar nothing says what made it: refused.
    fs::copy(p("a.csv"), p("b.csv")).unwrap();
    refused(
        &["sweep", s(&sw), "--out", s(&p("b.csv")), "--resume"],
        "sidecar",
    );

    // Shards made with different solver settings.
    ok(&on_cpu(&sw, &p("s1.csv"), &["--shard", "1/2"]));
    ok(&on_cpu(&sw, &p("s2.csv"), &["--shard", "2/2"]));
    ok(&on_cpu(
        &sw,
        &p("t2.csv"),
        &["--shard", "2/2", "--tolerance", "1e-8"],
    ));
    refused(&merge(&["s1.csv", "t2.csv"]), "different sweep or solver");
    // Incomplete set, repeated part.
    refused(&merge(&["s1.csv"]), "missing");
    refused(&merge(&["s1.csv", "s1.csv", "s2.csv"]), "more than once");
    // A part without its sidecar, and one cut short after it completed.
    fs::copy(p("s2.csv"), p("n2.csv")).unwrap();
    refused(&merge(&["s1.csv", "n2.csv"]), "sidecar");
    let text = fs::read_to_string(p("s2.csv")).unwrap();
    let cut = &text[..text.trim_end().rfind('\n').unwrap() + 1];
    fs::write(p("c2.csv"), cut).unwrap();
    fs::copy(p("s2.csv.json"), p("c2.csv.json")).unwrap();
    refused(&merge(&["s1.csv", "c2.csv"]), "rows are missing");
    assert!(!p("m.csv").exists() && !p("m.csv.partial").exists());
    // The right parts merge to the unsharded bytes, and --resume of the
    // unsharded sweep recognises the merged file as complete.
    ok(&[
        "merge",
        s(&p("s2.csv")),
        s(&p("s1.csv")),
        "--out",
        s(&p("m.csv")),
    ]);
    assert_eq!(fs::read(p("m.csv")).unwrap(), before);
    let o = run(&[
        "sweep",
        s(&sw),
        "--out",
        s(&p("m.csv")),
        "--backend",
        "cpu",
        "--resume",
    ]);
    assert!(
        o.status.success() && stderr(&o).contains("already complete"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn rows_are_never_labelled_with_values_they_were_not_computed_with() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("o.csv");
    let sweep = |name: &str, text: &str| {
        let p = d.join(name);
        fs::write(&p, text).unwrap();
        p
    };
    let base = "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n";
    // A flag against an axis of the same setting: both named.
    let tol = sweep(
        "tol.toml",
        &format!("{base}[[axis]]\nparam = \"tolerance\"\nvalues = [1e-6, 1e-8]\n"),
    );
    let e = refused(
        &["sweep", s(&tol), "--out", s(&out), "--tolerance", "1e-7"],
        "--tolerance",
    );
    assert!(
        e.contains("tol.toml:4") && e.contains("axis `tolerance`"),
        "{e}"
    );
    let dt = sweep(
        "dt.toml",
        &format!("{base}[[axis]]\nparam = \"dt\"\nvalues = [1e-7]\n"),
    );
    refused(
        &["sweep", s(&dt), "--out", s(&out), "--tolerance", "1e-7"],
        "axis `dt`",
    );
    // A flag against the file's [solver]: both named; the same value is fine.
    let solver = sweep("solver.toml", "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n[scene.solver]\nmethod = \"yoshida6\"\n[[axis]]\nparam = \"gap\"\nvalues = [0.0]\n");
    refused(
        &["sweep", s(&solver), "--out", s(&out), "--method", "verlet"],
        "[solver] method",
    );
    ok(&[
        "sweep",
        s(&solver),
        "--out",
        s(&out),
        "--method",
        "yoshida6",
        "--backend",
        "cpu",
    ]);
    // Two axes of one quantity.
    for (a, b) in [
        ("mass[1]", "mass"),
        ("mass[1]", "density[1]"),
        ("velocity[0]", "launch.height"),
        ("gap", "gap[0]"),
    ] {
        let two = sweep("two.toml", &format!("{base}[[axis]]\nparam = \"{a}\"\nvalues = [1.0]\n[[axis]]\nparam = \"{b}\"\nvalues = [0.5]\n"));
        refused(&["sweep", s(&two), "--out", s(&out)], "already sets");
    }
    // Integer params take integers only.
    for axis in ["values = [3, 4.5]", "linspace = [3, 4, 3]"] {
        let int = sweep(
            "int.toml",
            &format!("{base}[[axis]]\nparam = \"balls\"\n{axis}\n"),
        );
        refused(&["sweep", s(&int), "--out", s(&out)], "whole numbers only");
    }
    let lb = sweep("lb.toml", "[scene]\nballs = 5\n[scene.launch]\nballs = 1\nvelocity = 1.0\n[[axis]]\nparam = \"launch.balls\"\nvalues = [1.5]\n");
    refused(&["sweep", s(&lb), "--out", s(&out)], "whole numbers only");
}

#[test]
fn absurd_requests_are_refused_early_with_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 2, 2);
    let out = d.join("o.csv");
    refused(
        &["sweep", s(&sw), "--out", s(&out), "--threads", "100000"],
        "per core",
    );
    refused(
        &["sweep", s(&sw), "--out", s(&out), "--threads", "0"],
        "1 ..=",
    );
    refused(
        &["sweep", s(&sw), "--out", s(&out), "--tolerance", "-1"],
        "must be > 0",
    );
    refused(
        &["sweep", s(&sw), "--out", s(&out), "--tolerance", "1e-14"],
        "round-off floor",
    );
    refused(
        &[
            "sweep",
            s(&sw),
            "--out",
            s(&out),
            "--tolerance",
            "1e-6",
            "--precision",
            "f32",
        ],
        "round-off floor",
    );
    assert!(!out.exists() && !d.join("o.csv.partial").exists());
    // A trace of gigabytes is refused before the run, with a step that fits.
    let trace = d.join("t.csv");
    refused(
        &[
            "run",
            "cradle-1",
            "--trace",
            s(&trace),
            "--trace-dt",
            "1e-15",
        ],
        "--trace-dt ≥",
    );
    refused(
        &["run", "cradle-1", "--trace", s(&trace), "--trace-dt", "-1"],
        "a time > 0",
    );
    assert!(!trace.exists());
    // Long axes are computed on demand: a 10^7-value axis costs nothing
    // until its scenes run (here the last 100 of them, as one shard).
    let long = d.join("long.toml");
    fs::write(&long, "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n[[axis]]\nparam = \"gap\"\nlinspace = [0, 1e-5, 10000000]\n").unwrap();
    let t0 = Instant::now();
    ok(&on_cpu(&long, &out, &["--shard", "100000/100000"]));
    let text = fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 101);
    assert!(
        text.lines().last().unwrap().starts_with("9999999,1e-5,"),
        "{}",
        text.lines().last().unwrap()
    );
    let meta = fs::read(d.join("o.csv.json")).unwrap();
    assert!(
        meta.len() < 100_000,
        "the sidecar lists a range, not its values"
    );
    eprintln!(
        "10^7-value axis, one shard: {:.2} s",
        t0.elapsed().as_secs_f64()
    );
    // Too many scenes: refused from the axis lengths alone.
    fs::write(&long, "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n[[axis]]\nparam = \"gap\"\nlinspace = [0, 1e-5, 10000000]\n[[axis]]\nparam = \"mass[1]\"\nlinspace = [0.1, 1, 10000000]\n").unwrap();
    refused(
        &["sweep", s(&long), "--out", s(&out)],
        "≤ 1000000000 scenes",
    );
}

#[test]
fn no_desktop_session_no_spurious_error_lines() {
    let dir = tempfile::tempdir().unwrap();
    let sw = write_sweep(dir.path(), 2, 2);
    let out = dir.path().join("o.csv");
    let o = cradle()
        .args(["sweep", s(&sw), "--out", s(&out)])
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("WGPU_BACKEND")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("XDG_RUNTIME_DIR"), "{}", stderr(&o));
}

#[test]
fn run_and_slurm_apply_the_same_rules_as_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = d.join("s.toml");
    fs::write(
        &scene,
        "balls = 3\nvelocity = [1.0, 0, 0]\n[solver]\nmethod = \"yoshida6\"\n",
    )
    .unwrap();
    refused(&["run", s(&scene), "--method", "verlet"], "[solver] method");
    ok(&["run", s(&scene), "--method", "yoshida6"]);
    let sw = write_sweep(d, 2, 2);
    refused(
        &[
            "slurm",
            s(&sw),
            "--shards",
            "2",
            "--out",
            s(&sw),
            "--dir",
            s(&d.join("sl")),
        ],
        "is an input",
    );
    let tol = d.join("tol.toml");
    fs::write(&tol, "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n[[axis]]\nparam = \"tolerance\"\nvalues = [1e-6, 1e-7]\n").unwrap();
    refused(
        &[
            "slurm",
            s(&tol),
            "--shards",
            "2",
            "--tolerance",
            "1e-8",
            "--dir",
            s(&d.join("sl")),
        ],
        "axis `tolerance`",
    );
    // Job-script flags Slurm would not take, or that would add a line.
    let sl = d.join("sl");
    for (flag, value, needle) in [
        ("--cpus-per-task", "0", "≥ 1"),
        ("--time", "1:00:00\n#SBATCH --mem=1", "Slurm time limit"),
        ("--time", "1h", "Slurm time limit"),
        ("--partition", "gpu\n#SBATCH --x", "partition name"),
    ] {
        refused(
            &[
                "slurm",
                s(&sw),
                "--shards",
                "2",
                flag,
                value,
                "--dir",
                s(&sl),
            ],
            needle,
        );
    }
    ok(&[
        "slurm",
        s(&sw),
        "--shards",
        "2",
        "--time",
        "2-12:00",
        "--dir",
        s(&sl),
    ]);
    assert!(sl.join("array.sbatch").exists());
    fs::remove_dir_all(&sl).unwrap();
    assert!(!d.join("sl").exists(), "nothing written for a refused plan");
}

/// A file holds the format its name says, on every command that writes a
/// table: `fill` writes CSV, so `--out full.parquet` (CSV inside, before)
/// or `full.txt` is refused and nothing is written; `slurm --out
/// big.parquet` writes its shards as Parquet, so the job array's merge
/// joins them into big.parquet (before: CSV shards, whose merge into
/// .parquet was refused after the whole array), the same rows as the
/// unsharded run; a merged name that says no format is refused at once.
#[test]
fn every_table_is_written_in_the_format_its_name_says() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, refined) = write_refined(d);
    let table = d.join("r.parquet");
    ok(&on_cpu(&refined, &table, &[]));
    for name in ["full.parquet", "full.pq", "full.txt"] {
        let out = d.join(name);
        refused(
            &["fill", s(&table), "--out", s(&out)],
            "a name ending in .csv (fill writes CSV",
        );
        assert!(!out.exists(), "{name}");
    }
    ok(&["fill", s(&table), "--out", s(&d.join("full.csv"))]);

    let sw = write_sweep(d, 3, 4);
    let sl = d.join("sl");
    let slurm = |out: &Path| {
        vec![
            "slurm".to_string(),
            s(&sw).into(),
            "--shards".into(),
            "2".into(),
            "--out".into(),
            s(out).into(),
            "--dir".into(),
            s(&sl).into(),
        ]
    };
    refused(&slurm(&d.join("big.txt")), "the merged table's format");
    assert!(!sl.exists(), "nothing written for a refused plan");
    let big = d.join("big.parquet");
    let args = slurm(&big);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let array = fs::read_to_string(sl.join("array.sbatch")).unwrap();
    assert!(
        array.contains("-of-2.parquet") && !array.contains(".csv"),
        "{array}"
    );
    // The scripts as Slurm would run them (each task, then the merge).
    for k in ["1", "2"] {
        let o = Std::new("bash")
            .arg(sl.join("array.sbatch"))
            .env("SLURM_ARRAY_TASK_ID", k)
            .output()
            .unwrap();
        assert!(o.status.success(), "task {k}: {}", stderr(&o));
    }
    let o = Std::new("bash")
        .arg(sl.join("merge.sbatch"))
        .output()
        .unwrap();
    assert!(o.status.success(), "merge: {}", stderr(&o));
    let whole = d.join("whole.parquet");
    ok(&on_cpu(&sw, &whole, &[]));
    let read = hertz_cradle::output::parquet_file::read_text;
    assert_eq!(read(&big).unwrap(), read(&whole).unwrap());
}

/// A trace (`cradle run --trace`) given where a sweep's table goes says
/// what it is and how to plot it, exit 2 — not "not a cradle sidecar
/// (missing field `tool`)", as its own sidecar read before.
#[test]
fn a_trace_given_for_a_table_says_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for name in ["t.csv", "t.parquet"] {
        let trace = d.join(name);
        ok(&["run", "cradle-1", "--trace", s(&trace)]);
        let png = d.join("o.png");
        let out = d.join("o.csv");
        let words = |a: &[&str]| a.iter().map(|w| w.to_string()).collect::<Vec<_>>();
        for args in [
            plot_args(&trace, &png),
            words(&["explore", s(&trace), "--port", "0"]),
            words(&["fill", s(&trace), "--out", s(&out)]),
            words(&["merge", s(&trace), "--out", s(&out)]),
        ] {
            let e = refused(&args, "a trace (of cradle-1), not a sweep's table");
            assert!(
                e.contains(&format!("cradle plot --trace {}", s(&trace))) && !e.contains("shard"),
                "{args:?}: {e}"
            );
        }
        assert!(!png.exists() && !out.exists());
    }
}

/// Parquet output keeps every promise of the CSV: a disk that fills or a
/// kill -9 loses no whole segment, `--resume` finishes the same bytes as an
/// uninterrupted run (segments end at fixed ids), and the values are the
/// CSV's exactly (compared through their text, the CSV's shortest
/// round-trip form: equal text is equal bits).
#[test]
fn parquet_output_survives_disk_full_and_kills_and_holds_the_csv_values() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sw = write_sweep(d, 14, 10_000); // 140,000 scenes: 3 segments
    let reference = d.join("ref.parquet");
    ok(&on_cpu(&sw, &reference, &[]));
    let want = fs::read(&reference).unwrap();
    assert_eq!(&want[..4], b"PAR1");
    let csv = d.join("ref.csv");
    ok(&on_cpu(&sw, &csv, &[]));
    let (header, rows) = hertz_cradle::output::parquet_file::read_text(&reference).unwrap();
    let mut r = csv::Reader::from_path(&csv).unwrap();
    assert_eq!(r.headers().unwrap().iter().collect::<Vec<_>>(), header);
    let mut n = 0;
    for (rec, row) in r.records().zip(&rows) {
        assert_eq!(rec.unwrap().iter().collect::<Vec<_>>(), *row);
        n += 1;
    }
    assert_eq!((n, rows.len()), (140_000, 140_000));
    // `cradle plot` draws the same picture from either file.
    let pngs: Vec<PathBuf> = ["csv", "parquet"]
        .iter()
        .map(|e| {
            let png = d.join(format!("map_{e}.png"));
            let table = if *e == "csv" { &csv } else { &reference };
            ok(&[
                "plot",
                s(table),
                "--x",
                "gap",
                "--y",
                "mass[2]",
                "--z",
                "ejected",
                "--out",
                s(&png),
            ]);
            png
        })
        .collect();
    assert_eq!(fs::read(&pngs[0]).unwrap(), fs::read(&pngs[1]).unwrap());

    // Disk full while appending the second segment.
    let out = d.join("full.parquet");
    let o = cradle()
        .args(on_cpu(&sw, &out, &[]))
        .env("CRADLE_FAILPOINT", "append:2")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("No space left on device"));
    assert!(!out.exists());
    ok(&on_cpu(&sw, &out, &["--resume"]));
    assert_eq!(fs::read(&out).unwrap(), want);

    // Killed while it writes the second segment (of three, ~5 MB each),
    // then resumed.
    let out = d.join("o.parquet");
    let partial = d.join("o.parquet.partial");
    let mut child = Std::new(assert_cmd::cargo::cargo_bin("cradle"))
        .args(on_cpu(&sw, &out, &["--threads", "1"]))
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let at = want.len() as u64 / 2;
    while fs::metadata(&partial).map_or(0, |m| m.len()) < at
        && t0.elapsed() < Duration::from_secs(60)
        && child.try_wait().unwrap().is_none()
    {
        std::thread::sleep(Duration::from_millis(2));
    }
    let killed = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        killed && !out.exists(),
        "the run ended before it could be killed"
    );
    ok(&on_cpu(&sw, &out, &["--resume"]));
    assert_eq!(fs::read(&out).unwrap(), want);
    let meta = sidecar(&d.join("o.parquet.json"));
    assert_eq!(meta["resumed_from_row"].as_u64().unwrap() % 65_536, 0);
    assert!(meta["resumed_from_row"].as_u64().unwrap() > 0);
    assert_eq!(
        meta["scenes_ok"].as_u64().unwrap() + meta["scenes_not_ok"].as_u64().unwrap(),
        140_000
    );
    // Shards merge into the unsharded file's rows; a CSV part is refused.
    for k in 1..=3 {
        let part = d.join(format!("p{k}.parquet"));
        ok(&on_cpu(&sw, &part, &["--shard", &format!("{k}/3")]));
    }
    let merged = d.join("m.parquet");
    let parts: Vec<PathBuf> = (1..=3).map(|k| d.join(format!("p{k}.parquet"))).collect();
    let mut args = vec!["merge".to_string()];
    args.extend(parts.iter().map(|p| s(p).to_string()));
    args.extend(["--out".into(), s(&merged).into()]);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(
        hertz_cradle::output::parquet_file::read_text(&merged).unwrap(),
        (header, rows)
    );
    refused(
        &[
            "merge",
            s(&parts[0]),
            s(&csv),
            "--out",
            s(&d.join("x.parquet")),
        ],
        "merge parts of one format",
    );
}

/// Every input is opened through one reader: a FIFO (which would block the
/// open until a writer comes), a device (/dev/zero never ends) or a
/// directory is refused at once, exit 2, naming it — as a scene, a sweep's
/// scene file, a point list, a table to plot, fill, merge or explore, and a
/// trace to plot.
#[test]
fn inputs_that_are_not_regular_files_are_refused_at_once() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let fifo = d.join("pipe");
    assert!(Std::new("mkfifo").arg(&fifo).status().unwrap().success());
    let sweep = |name: &str, text: &str| {
        let p = d.join(name);
        fs::write(&p, text).unwrap();
        p
    };
    let scene_fifo = sweep("a.toml", "scene = \"pipe\"\n");
    let points_zero = sweep(
        "b.toml",
        "[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n[points]\nfile = \"/dev/zero\"\n",
    );
    let out = d.join("o.csv");
    let png = d.join("o.png");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["run", s(&fifo)], "a FIFO"),
        (vec!["run", "/dev/zero"], "a character device"),
        (vec!["run", s(d)], "a directory"),
        (vec!["sweep", s(&scene_fifo), "--out", s(&out)], "a FIFO"),
        (
            vec!["sweep", s(&points_zero), "--out", s(&out)],
            "/dev/zero",
        ),
        (
            vec![
                "plot",
                "/dev/zero",
                "--x",
                "a",
                "--y",
                "b",
                "--z",
                "c",
                "--out",
                s(&png),
            ],
            "/dev/zero",
        ),
        (
            vec!["plot", "--trace", s(&fifo), "--out", s(&png)],
            "a FIFO",
        ),
        (vec!["fill", s(&fifo), "--out", s(&out)], "pipe"),
        (vec!["explore", s(&fifo)], "a FIFO"),
    ];
    for (args, needle) in cases {
        let t = Instant::now();
        let mut cmd = Std::new(assert_cmd::cargo::cargo_bin("cradle"));
        let mut child = cmd
            .args(&args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // A hang is the failure this test is about: give up after 20 s.
        while child.try_wait().unwrap().is_none() {
            if t.elapsed() > Duration::from_secs(20) {
                child.kill().unwrap();
                panic!("{args:?} hangs");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let o = child.wait_with_output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(needle), "{args:?}: {e}");
        assert!(!out.exists() && !png.exists(), "{args:?} wrote an output");
    }
}

/// `run --trace` and `plot --out` over an existing file are atomic: a full
/// disk when the new file is finished leaves the previous one whole and no
/// temporary file beside it.
#[test]
fn trace_and_plot_keep_the_previous_file_when_the_disk_fills() {
    let d = tempfile::tempdir().unwrap();
    let d = d.path();
    let (trace, png) = (d.join("t.csv"), d.join("p.png"));
    ok(&["run", "cradle-1", "--trace", s(&trace)]);
    ok(&["plot", "--trace", s(&trace), "--out", s(&png)]);
    let (t0, p0) = (fs::read(&trace).unwrap(), fs::read(&png).unwrap());
    let full = |args: &[&str]| {
        let o = cradle()
            .args(args)
            .env("CRADLE_FAILPOINT", "publish:1")
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(e.contains("No space left"), "{args:?}: {e}");
    };
    full(&[
        "run",
        "cradle-1",
        "--trace",
        s(&trace),
        "--trace-dt",
        "1e-6",
    ]);
    full(&[
        "plot",
        "--trace",
        s(&trace),
        "--out",
        s(&png),
        "--title",
        "x",
    ]);
    assert_eq!(fs::read(&trace).unwrap(), t0, "the trace was replaced");
    assert_eq!(fs::read(&png).unwrap(), p0, "the plot was replaced");
    let mut left: Vec<_> = fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    // The trace, its sidecar (the first run's) and the plot: no temporary file.
    assert_eq!(
        left,
        ["p.png", "t.csv", "t.csv.json"],
        "temporary files left"
    );
}

/// [`write_sweep`]'s 9 × 9 sweep, and the same with a `[refine]` of
/// `ejected` (stride 4) in `refined.toml`.
fn write_refined(dir: &Path) -> (PathBuf, PathBuf) {
    let sw = write_sweep(dir, 9, 9);
    let refined = dir.join("refined.toml");
    fs::write(
        &refined,
        fs::read_to_string(&sw).unwrap() + "[refine]\ncolumn = \"ejected\"\nstride = 4\n",
    )
    .unwrap();
    (sw, refined)
}

/// `cradle plot TABLE --x mass[2] --y gap --z ejected --out OUT` (the map of
/// [`write_sweep`]'s tables).
fn plot_args(table: &Path, out: &Path) -> Vec<String> {
    [
        "plot",
        s(table),
        "--x",
        "mass[2]",
        "--y",
        "gap",
        "--z",
        "ejected",
        "--out",
        s(out),
    ]
    .map(String::from)
    .to_vec()
}

/// Flip one byte of `path` at `at` (a digit to another digit, anything else
/// to its complement).
fn flip(path: &Path, at: usize) {
    let mut b = fs::read(path).unwrap();
    b[at] = match b[at] {
        b'0'..=b'8' => b[at] + 1,
        b'9' => b'0',
        x => !x,
    };
    fs::write(path, b).unwrap();
}

/// A table is read only with its sidecar's promise kept (rows, length,
/// CRC-32 recorded when it was published): a refined table cut at a row
/// boundary, a CSV and a Parquet table with one flipped byte are refused by
/// merge, fill, plot and explore with exit 2 naming the file and what
/// differs; no output names an input's sidecar; a table without a sidecar
/// is read as a plain table, and one that is not there is said so alone.
#[test]
fn tables_are_read_only_with_their_sidecars_promise() {
    let d = tempfile::tempdir().unwrap();
    let (sw, refined) = write_refined(d.path());
    let (plain, cut, pq) = (
        d.path().join("plain.csv"),
        d.path().join("cut.csv"),
        d.path().join("t.parquet"),
    );
    ok(&on_cpu(&sw, &plain, &[]));
    ok(&on_cpu(&refined, &cut, &[]));
    ok(&on_cpu(&sw, &pq, &[]));
    let seal = &sidecar(&d.path().join("plain.csv.json"))["table"];
    let lines = fs::read_to_string(&plain).unwrap().lines().count() as u64;
    assert_eq!(seal["rows"], lines - 1, "{seal}");
    assert_eq!(seal["bytes"], fs::metadata(&plain).unwrap().len(), "{seal}");
    let out = d.path().join("o.csv");
    let png = d.path().join("o.png");
    let plot = |t: &Path| plot_args(t, &png);
    // Every reader takes the intact tables.
    ok(&["merge", s(&cut), "--out", s(&out)]);
    ok(&["fill", s(&cut), "--out", s(&out)]);
    for t in [&plain, &cut, &pq] {
        let o = run(&plot(t));
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // A refined table cut at a row boundary, sidecar intact.
    let text = fs::read_to_string(&cut).unwrap();
    let body = text.trim_end_matches('\n');
    fs::write(&cut, &text[..body.rfind('\n').unwrap() + 1]).unwrap();
    // One flipped byte in a CSV's last row and in a Parquet file's middle.
    let n = fs::metadata(&plain).unwrap().len() as usize;
    flip(&plain, n - 3);
    flip(&pq, fs::metadata(&pq).unwrap().len() as usize / 2);
    fs::remove_file(&out).unwrap();
    for (t, what) in [
        (&cut, "rows are missing"),
        (&plain, "CRC-32"),
        (&pq, "CRC-32"),
    ] {
        let e = refused(
            &["merge", s(t), "--out", s(&out)],
            "is not the table its sidecar",
        );
        assert!(e.contains(s(t)) && e.contains(what), "{e}");
        refused(&plot(t), "is not the table its sidecar");
        let o = cradle()
            .args(["explore", s(t), "--port", "0"])
            .timeout(Duration::from_secs(60))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "explore {t:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("is not the table its sidecar"),
            "{}",
            stderr(&o)
        );
    }
    refused(
        &["fill", s(&cut), "--out", s(&out)],
        "is not the table its sidecar",
    );
    assert!(!out.exists(), "nothing written");
    // No output may name an input's sidecar (it would be replaced).
    let json = d.path().join("cut.csv.json");
    let before = fs::read(&json).unwrap();
    refused(&["fill", s(&cut), "--out", s(&json)], "beside the input");
    refused(&["merge", s(&cut), "--out", s(&json)], "beside the input");
    assert_eq!(fs::read(&json).unwrap(), before);
    // Without a sidecar a table is a plain table.
    fs::remove_file(d.path().join("plain.csv.json")).unwrap();
    let o = run(&plot(&plain));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("read as a plain table"),
        "{}",
        stderr(&o)
    );
    // A table that is not there is said so, without the plain-table note.
    let e = refused(&plot(&d.path().join("gone.csv")), "cannot read");
    assert!(e.contains("gone.csv") && !e.contains("plain table"), "{e}");
}

/// Every command that writes a file holds its lock (`FILE.lock`) while it
/// writes: with another writer holding it, `fill --out`, `run --trace` and
/// `plot --out` into the same file exit 2 naming the holder and leave the
/// previous file as it was (two fills at once used to mix their rows in
/// one temporary file, one of them exiting 0).
#[test]
fn fill_trace_and_plot_refuse_a_file_another_writer_holds() {
    let d = tempfile::tempdir().unwrap();
    let (_, refined) = write_refined(d.path());
    let table = d.path().join("r.csv");
    ok(&on_cpu(&refined, &table, &[]));
    let out = d.path().join("o.csv");
    fs::write(&out, "previous\n").unwrap();
    let scene = d.path().join("scene.toml");
    let holder = fs::File::create(d.path().join("o.csv.lock")).unwrap();
    holder.lock().unwrap();
    for args in [
        vec!["fill", s(&table), "--out", s(&out)],
        vec!["run", s(&scene), "--trace", s(&out)],
    ] {
        refused(&args, "is being written by another cradle");
        assert_eq!(fs::read_to_string(&out).unwrap(), "previous\n", "{args:?}");
    }
    let png = d.path().join("o.png");
    let png_holder = fs::File::create(d.path().join("o.png.lock")).unwrap();
    png_holder.lock().unwrap();
    refused(
        &plot_args(&table, &png),
        "is being written by another cradle",
    );
    assert!(!png.exists());
    // Once the holder is gone, the same commands write.
    drop((holder, png_holder));
    ok(&["fill", s(&table), "--out", s(&out)]);
    assert!(fs::read_to_string(&out).unwrap().starts_with("id,"));
}

/// `explore` of a table it cannot use exits 2 (bad input) naming the file,
/// at once: missing, empty, a header alone, not a table, a ragged row.
#[test]
fn explore_refuses_unusable_tables_with_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let cases = [
        ("missing.csv", None),
        ("empty.csv", Some("")),
        ("header.csv", Some("id,mass,status\n")),
        ("fake.csv", Some("hello world\n")),
        ("ragged.csv", Some("id,a\n0,1\n1\n")),
        // The Parquet reader's "Corrupt footer" named no file, exit 1.
        ("corrupt.parquet", Some("PAR1 not a parquet file PAR1")),
    ];
    for (name, text) in cases {
        let p = d.path().join(name);
        if let Some(t) = text {
            fs::write(&p, t).unwrap();
        }
        let o = cradle()
            .args(["explore", s(&p), "--port", "0"])
            .timeout(Duration::from_secs(60))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(name), "{name}: {}", stderr(&o));
    }
    // `fill` of a missing table says so (it said "not a refined sweep's table").
    let e = refused(
        &[
            "fill",
            s(&d.path().join("missing.csv")),
            "--out",
            s(&d.path().join("f.csv")),
        ],
        "no such file",
    );
    assert!(e.contains("missing.csv"), "{e}");
}

/// An output directory that cannot be written (made immutable with
/// `chattr +i`, which binds root too) is exit 2 naming the path for every
/// command that writes, before any work; skipped where chattr is not
/// available (not root, or a filesystem without the attribute).
#[test]
fn an_unwritable_output_directory_is_exit_2_for_every_writer() {
    let d = tempfile::tempdir().unwrap();
    let (sw, refined) = write_refined(d.path());
    let (table, filled_from) = (d.path().join("t.csv"), d.path().join("r.csv"));
    ok(&on_cpu(&sw, &table, &[]));
    ok(&on_cpu(&refined, &filled_from, &[]));
    let ro = d.path().join("ro");
    fs::create_dir(&ro).unwrap();
    let immutable = Std::new("chattr").arg("+i").arg(&ro).status();
    if !immutable.is_ok_and(|s| s.success()) || fs::write(ro.join("probe"), "x").is_ok() {
        eprintln!("SKIPPED: chattr +i is not available here");
        return;
    }
    struct Unlock<'a>(&'a Path);
    impl Drop for Unlock<'_> {
        fn drop(&mut self) {
            let _ = Std::new("chattr").arg("-i").arg(self.0).status();
        }
    }
    let _unlock = Unlock(&ro);
    let o = |name: &str| s(&ro.join(name)).to_string();
    let scene = d.path().join("scene.toml");
    let cases: Vec<Vec<String>> = vec![
        on_cpu(&sw, &ro.join("a.csv"), &[])
            .iter()
            .map(|a| a.to_string())
            .collect(),
        vec!["merge".into(), s(&table).into(), "--out".into(), o("m.csv")],
        vec![
            "fill".into(),
            s(&filled_from).into(),
            "--out".into(),
            o("f.csv"),
        ],
        plot_args(&table, &ro.join("p.png")),
        vec!["run".into(), s(&scene).into(), "--trace".into(), o("t.csv")],
        vec![
            "slurm".into(),
            s(&sw).into(),
            "--shards".into(),
            "2".into(),
            "--dir".into(),
            o("sl"),
            "--out".into(),
            o("x.csv"),
        ],
    ];
    for args in cases {
        let e = refused(&args, s(&ro));
        assert!(!e.contains("panicked"), "{e}");
    }
    assert_eq!(fs::read_dir(&ro).unwrap().count(), 0, "nothing written");
}

/// `merge` and `fill` fail at each publication (merge: its sidecar, then
/// its table; fill: its table) without a cut-off file under the output's
/// name, and run again give the bytes of an undisturbed run. A failure
/// between merge's two renames leaves the previous table beside the new
/// sidecar: every reader refuses that pair, naming the command to re-run.
#[test]
fn merge_and_fill_publish_whole_files_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |n: &str| d.join(n).display().to_string();
    let (sw, refined) = write_refined(d);
    for k in 1..=2 {
        ok(&on_cpu(
            &sw,
            &d.join(format!("p{k}.csv")),
            &["--shard", &format!("{k}/2")],
        ));
    }
    ok(&on_cpu(&refined, &d.join("r.csv"), &[]));
    let merge = |out: &str| {
        vec![
            "merge".to_string(),
            p("p1.csv"),
            p("p2.csv"),
            "--out".into(),
            p(out),
        ]
    };
    let fill = |out: &str| vec!["fill".to_string(), p("r.csv"), "--out".into(), p(out)];
    ok(&merge("m_ref.csv")
        .iter()
        .map(|a| a.as_str())
        .collect::<Vec<_>>());
    ok(&fill("f_ref.csv")
        .iter()
        .map(|a| a.as_str())
        .collect::<Vec<_>>());
    type Args<'a> = &'a dyn Fn(&str) -> Vec<String>;
    let cases: [(&str, Args, u64); 3] = [("m", &merge, 1), ("m", &merge, 2), ("f", &fill, 1)];
    for (name, args, k) in cases {
        let out = format!("{name}{k}.csv");
        let o = cradle()
            .args(args(&out))
            .env("CRADLE_FAILPOINT", format!("publish:{k}"))
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name} publish:{k}: {e}");
        assert!(
            e.contains("No space left on device") && e.contains(&out),
            "{e}"
        );
        assert!(
            !d.join(&out).exists(),
            "{name} publish:{k}: a failed run published its table"
        );
        assert!(!d.join(format!("{out}.tmp")).exists());
        ok(&args(&out).iter().map(|a| a.as_str()).collect::<Vec<_>>());
        let want = fs::read(d.join(format!("{name}_ref.csv"))).unwrap();
        assert_eq!(fs::read(d.join(&out)).unwrap(), want, "{name} publish:{k}");
    }
    // The previous table under the new sidecar (merge failed between its renames).
    let other = d.join("other.toml");
    fs::write(
        &other,
        fs::read_to_string(&sw)
            .unwrap()
            .replace("0.5, 9]", "0.6, 9]"),
    )
    .unwrap();
    for k in 1..=2 {
        ok(&on_cpu(
            &other,
            &d.join(format!("q{k}.csv")),
            &["--shard", &format!("{k}/2")],
        ));
    }
    let before = fs::read(d.join("m1.csv")).unwrap();
    let o = cradle()
        .args(["merge", &p("q1.csv"), &p("q2.csv"), "--out", &p("m1.csv")])
        .env("CRADLE_FAILPOINT", "publish:2")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(
        fs::read(d.join("m1.csv")).unwrap(),
        before,
        "the previous table is untouched"
    );
    let png = d.join("m1.png");
    let e = refused(
        &plot_args(&d.join("m1.csv"), &png),
        "is not the table its sidecar",
    );
    assert!(
        e.contains("run the command that made it again") && e.contains("q1.csv"),
        "{e}"
    );
    assert!(!png.exists());
}
