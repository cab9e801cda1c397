//! The tolerance contract on chains unlike the step rule's fit (issue #43;
//! results/chains.md): a family of chains (dimers, random radii and masses,
//! tapers, impurities, a heavy striker, gaps, precompression, a head-on
//! collision, a pulse, damped ones, sensitive ones), each run under the error control at
//! tolerances 1e-4, 1e-6 and 1e-8 (`cradle run`'s path:
//! `backend::run_chains_controlled` on the CPU, one thread), and each at a
//! range of steps with its twin (the estimate's calibration pairs). Writes
//! each chain's compiled beads and every run's outcome as JSON for the
//! independent reference, `scripts/chain_reference.py` (scipy's DOP853),
//! which measures every run's true error and writes the tables.
//!
//! `cargo run --release --example chain_contract -- target/chain_contract.json [name-filter]`
//!
//! With `--backend cpu|gpu` and `--precision f64|df64` (lists, comma
//! separated) it runs only the contract's controlled runs, every chain of
//! one backend, precision and tolerance as one batch (a sweep's path),
//! each run labelled with its backend and precision (`--skip NAME`: leave out the chains whose
//! name contains NAME): the contract on a lent GPU
//! (`scripts/chain_contract_table.py --backends`).

use hertz_cradle::backend::gpu::{find_adapter, Gpu, Want};
use hertz_cradle::backend::{cpu::Cpu, run_chains_controlled, Backend, ChainJob};
use hertz_cradle::choice::Choice;
use hertz_cradle::engine::granular::{self, control, Beads, ChainOutcome, NoRows};
use hertz_cradle::engine::{Overrides, Solver};
use hertz_cradle::scene::{Precision, Scene};
use serde_json::{json, Value};
use std::time::Instant;

/// A small deterministic generator (xorshift64*): the family's random
/// chains are the same on every machine.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545F4914F6CDD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn array(&mut self, n: usize, lo: f64, hi: f64) -> String {
        let v: Vec<String> = (0..n)
            .map(|_| format!("{:e}", lo + (hi - lo) * self.next()))
            .collect();
        format!("[{}]", v.join(", "))
    }
}

/// The family: (name, scene TOML).
fn family() -> Vec<(String, String)> {
    // Top-level keys (`top`) before the tables (`extra`).
    let scene = |top: &str, extra: &str| {
        format!("balls = 200\n{top}[probes]\nbeads = [50, 150]\n[stop]\nduration = 0.003\n{extra}")
    };
    let base = |extra: &str| scene("radius = 0.005\n", extra);
    let struck = |extra: &str| base(&format!("[launch]\nballs = 1\nvelocity = 0.1\n{extra}"));
    let struck_with = |top: &str| scene(top, "[launch]\nballs = 1\nvelocity = 0.1\n");
    let mut f: Vec<(String, String)> = vec![];
    let mut add = |name: &str, text: String| f.push((name.to_string(), text));
    add("uniform (the fit's kind)", struck(""));
    for (r, wall) in [
        (1.5, true),
        (1.9, true),
        (1.9, false),
        (2.5, false),
        (3.5, true),
        (4.0, false),
    ] {
        add(
            &format!(
                "dimer R 5 / {r} mm, {}",
                if wall {
                    "wall after the last"
                } else {
                    "free ends"
                }
            ),
            struck(&format!(
                "[pattern]\nradius = [0.005, {}]\n{}",
                r * 1e-3,
                if wall { "[walls]\nright = true\n" } else { "" }
            )),
        );
    }
    for seed in 1..=3u64 {
        let mut g = Rng(0x9E3779B97F4A7C15 ^ seed);
        add(
            &format!("random radii 3.5-6.5 mm, seed {seed}"),
            struck_with(&format!("radius = {}\n", g.array(200, 0.0035, 0.0065))),
        );
    }
    let mut g = Rng(0xD1B54A32D192ED03);
    add(
        "random densities 2000-12000 kg/m3",
        struck_with(&format!(
            "radius = 0.005\ndensity = {}\n",
            g.array(200, 2000.0, 12000.0)
        )),
    );
    add(
        "linear taper 0.2%/bead",
        struck("[taper]\nkind = \"linear\"\nratio = 0.002\n"),
    );
    add("ratio taper 0.3%/bead", struck("[taper]\nratio = 0.003\n"));
    add(
        "heavy impurity (bead 100, 5x density)",
        struck("[impurity]\nbeads = [100]\ndensity = 39250.0\n"),
    );
    add(
        "light impurity (bead 100, R 2 mm)",
        struck("[impurity]\nbeads = [100]\nradius = 0.002\n"),
    );
    add(
        "heavy striker (bead 0, 10x mass)",
        struck("[impurity]\nbeads = [0]\nmass = 0.0411\n"),
    );
    add("gaps of 2 um", struck_with("radius = 0.005\ngap = 2e-6\n"));
    add(
        "precompressed 10 N, struck at 1 m/s",
        base("[launch]\nballs = 1\nvelocity = 1.0\n[walls]\nleft = true\nright = true\nprecompression = 10.0\n"),
    );
    {
        let mut v = vec!["0.0".to_string(); 200];
        v[0] = "0.1".into();
        v[199] = "-0.1".into();
        add(
            "head-on collision (0.1 m/s from each end)",
            scene(
                &format!("radius = 0.005\nvelocity = [{}]\n", v.join(", ")),
                "",
            ),
        );
    }
    add(
        "pulse 1 N x 40 us, walls",
        base(
            "[pulse]\nbead = 0\nforce = 1.0\nduration = 4e-5\n[walls]\nleft = true\nright = true\n",
        ),
    );
    // Damped chains (issue #45): dashpots at every contact, air drag.
    add(
        "damped: uniform, viscosity 0.5 N s/m",
        struck("[damping]\nviscosity = 0.5\n"),
    );
    add(
        "damped: dimer R 5 / 2.5 mm, free ends, viscosity 1",
        struck("[pattern]\nradius = [0.005, 0.0025]\n[damping]\nviscosity = 1.0\n"),
    );
    add(
        "damped: precompressed 10 N, struck at 1 m/s, viscosity 5",
        base("[launch]\nballs = 1\nvelocity = 1.0\n[walls]\nleft = true\nright = true\nprecompression = 10.0\n[damping]\nviscosity = 5.0\n"),
    );
    add(
        "damped: gaps of 2 um, viscosity 1",
        scene(
            "radius = 0.005\ngap = 2e-6\n",
            "[launch]\nballs = 1\nvelocity = 0.1\n[damping]\nviscosity = 1.0\n",
        ),
    );
    add(
        "damped: pulse 1 N x 40 us, walls, viscosity 0.5, air drag 50/s",
        base(
            "[pulse]\nbead = 0\nforce = 1.0\nduration = 4e-5\n[walls]\nleft = true\nright = true\n[damping]\nviscosity = 0.5\nair_drag = 50.0\n",
        ),
    );
    let mut g = Rng(0xA0761D6478BD642F);
    add(
        "sensitive: 30 random beads with 20 um gaps between walls, 30 ms",
        format!(
            "balls = 30\nradius = {}\ngap = 2e-5\n[launch]\nballs = 1\nvelocity = 0.1\n[walls]\nleft = true\nright = true\n[probes]\nbeads = [10, 20]\n[stop]\nduration = 0.03\n",
            g.array(30, 0.0035, 0.0065)
        ),
    );
    f
}

fn outcome(o: &ChainOutcome, secs: f64, n: usize) -> Value {
    json!({
        "status": o.status.name(),
        "estimate": o.error_estimate,
        "h": o.dt,
        "t_end": o.t_end,
        "steps": o.steps,
        "bead_steps": o.steps as f64 * n as f64,
        "regions": o.regions,
        "seconds": secs,
        "v": o.v,
        "probes": o.probes.iter().map(|p| json!({"bead": p.bead, "arrival": p.arrival, "peak_v": p.peak_velocity})).collect::<Vec<_>>(),
    })
}

/// `--backend` and `--precision`: every chain at one tolerance in one
/// batch under the error control, for each backend, precision and
/// tolerance; the JSON is written after each batch (a capped run keeps the
/// batches it finished). `skip`: chains whose name contains it are left out.
fn across(path: &str, only: Option<&str>, skip: Option<&str>, backends: &str, precisions: &str) {
    let gpu = backends.contains("gpu").then(|| {
        let a = find_adapter(Want::Any).expect("a GPU adapter (--backend gpu)");
        Gpu::new(&a).expect("a GPU context")
    });
    let adapter = gpu.as_ref().map(|g| g.info().name.clone());
    let family: Vec<(String, Beads, Scene)> = family()
        .into_iter()
        .filter(|(name, _)| only.is_none_or(|o| name.contains(o)))
        .filter(|(name, _)| skip.is_none_or(|o| !name.contains(o)))
        .map(|(name, text)| {
            let s = Scene::from_toml_str("family", &text).unwrap();
            (name, Beads::from_scene(&s), s)
        })
        .collect();
    let mut runs: Vec<Vec<Value>> = vec![vec![]; family.len()];
    for backend in backends.split(',') {
        let b: &dyn Backend = match backend {
            "cpu" => &Cpu,
            "gpu" => gpu.as_ref().unwrap(),
            other => panic!("--backend {other}: cpu or gpu"),
        };
        for precision in precisions.split(',') {
            let prec =
                Precision::parse_flag("--precision", precision).unwrap_or_else(|e| panic!("{e}"));
            for tol in [1e-4, 1e-6, 1e-8] {
                let jobs: Vec<ChainJob> = family
                    .iter()
                    .map(|(_, beads, s)| {
                        let o = Overrides {
                            tolerance: Some(tol),
                            precision: Some(prec),
                            ..Default::default()
                        };
                        let solver = Solver::resolve(s, &o).unwrap();
                        // f32 is refused for chains, as a user would be.
                        granular::check_solver(&solver).unwrap_or_else(|e| panic!("{e}"));
                        ChainJob {
                            beads: beads.clone(),
                            plan: granular::plan(beads, &solver, None),
                        }
                    })
                    .collect();
                let t = Instant::now();
                let out =
                    run_chains_controlled(b, jobs.len(), &|k| Ok(Some(jobs[k].clone()))).unwrap();
                let secs = t.elapsed().as_secs_f64();
                eprintln!(
                    "{backend} {precision} {tol:e}: {} runs in {secs:.1} s",
                    out.len()
                );
                for (c, o) in out.iter().enumerate() {
                    let mut r = outcome(o, secs / out.len() as f64, family[c].1.n);
                    r["kind"] = json!("controlled");
                    r["tol"] = json!(tol);
                    r["backend"] = json!(backend);
                    r["precision"] = json!(precision);
                    runs[c].push(r);
                }
                let chains: Vec<Value> = family
                    .iter()
                    .zip(&runs)
                    .map(|((name, b, _), runs)| chain_json(name, b, runs.clone()))
                    .collect();
                let doc = json!({ "chains": chains, "adapter": adapter });
                std::fs::write(path, serde_json::to_string(&doc).unwrap()).unwrap();
            }
        }
    }
    eprintln!("wrote {path}");
}

/// A chain's compiled beads (what the reference integrates) and its runs.
fn chain_json(name: &str, b: &Beads, runs: Vec<Value>) -> Value {
    json!({
        "name": name,
        "n": b.n,
        "mass": b.mass,
        "k": b.k,
        "d0": b.d0,
        "v0": b.v0,
        "pulse": b.pulse.as_ref().map(|p| json!({"bead": p.bead, "force": p.force, "duration": p.duration})),
        "probes": b.probes,
        "viscosity": b.viscosity,
        "air_drag": b.air_drag,
        "v_scale": b.v_scale(),
        "t_scale": b.time_scale(),
        "runs": runs,
    })
}

fn main() {
    let mut args = vec![];
    let (mut backends, mut precisions, mut skip) = (None, None, None);
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--backend" => backends = it.next(),
            "--precision" => precisions = it.next(),
            "--skip" => skip = it.next(),
            _ => args.push(a),
        }
    }
    let mut args = args.into_iter();
    let path = args
        .next()
        .unwrap_or_else(|| "target/chain_contract.json".into());
    let only = args.next();
    if backends.is_some() || precisions.is_some() {
        let b = backends.unwrap_or_else(|| "cpu".into());
        let p = precisions.unwrap_or_else(|| "f64".into());
        return across(&path, only.as_deref(), skip.as_deref(), &b, &p);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut chains = vec![];
    for (name, text) in family() {
        if only.as_ref().is_some_and(|o| !name.contains(o.as_str())) {
            continue;
        }
        let s = Scene::from_toml_str("family", &text).unwrap();
        let b = Beads::from_scene(&s);
        let solver_at = |tol: f64| {
            Solver::resolve(
                &s,
                &Overrides {
                    tolerance: Some(tol),
                    ..Default::default()
                },
            )
            .unwrap()
        };
        let mut runs = vec![];
        // The contract: each tolerance under the error control.
        for tol in [1e-4, 1e-6, 1e-8] {
            let job = ChainJob {
                beads: b.clone(),
                plan: granular::plan(&b, &solver_at(tol), None),
            };
            let t = Instant::now();
            let o = pool
                .install(|| run_chains_controlled(&Cpu, 1, &|_| Ok(Some(job.clone()))))
                .unwrap()
                .remove(0);
            let mut r = outcome(&o, t.elapsed().as_secs_f64(), b.n);
            r["kind"] = json!("controlled");
            r["tol"] = json!(tol);
            // The plain run the step rule alone gives (what rows were before).
            let t = Instant::now();
            let p = granular::run(&b, &job.plan, &mut NoRows);
            let mut plain = outcome(&p, t.elapsed().as_secs_f64(), b.n);
            plain["kind"] = json!("plain");
            plain["tol"] = json!(tol);
            runs.push(r);
            runs.push(plain);
        }
        // Calibration pairs: a run at the step rule's first guess for each
        // tolerance, and its twin as the control runs it.
        for (k, tol) in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
            .into_iter()
            .enumerate()
        {
            let plan = granular::plan(&b, &solver_at(tol), None);
            let fine = granular::run(&b, &plan, &mut NoRows);
            let twin = plan.rerun(
                &b,
                plan.h * control::TWIN_RATIO,
                fine.t_end,
                plan.refine.is_some(),
            );
            let coarse = granular::run(&b, &twin, &mut NoRows);
            // The twin without the local refinement (where the run has it).
            let plain = plan.rerun(&b, plan.h * control::TWIN_RATIO, fine.t_end, false);
            let mixed = granular::run(&b, &plain, &mut NoRows);
            for (o, role) in [(&fine, "fine"), (&coarse, "coarse"), (&mixed, "mixed")] {
                let mut r = outcome(o, 0.0, b.n);
                r["kind"] = json!("pair");
                r["pair"] = json!(k);
                r["role"] = json!(role);
                r["tol"] = json!(tol);
                runs.push(r);
            }
        }
        eprintln!("{name}: {} runs", runs.len());
        chains.push(chain_json(&name, &b, runs));
    }
    std::fs::write(
        &path,
        serde_json::to_string(&json!({ "chains": chains })).unwrap(),
    )
    .unwrap();
    eprintln!("wrote {path}");
}
