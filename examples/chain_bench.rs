//! The tables of results/chains.md: granular chains against theory, the
//! work-precision of each method on a struck 1,000-bead chain, the
//! tolerance on chains unlike the fit's, and the cost per bead-step from
//! 10^2 to 10^4 beads.
//!
//! `cargo run --release --example chain_bench`

use hertz_cradle::engine::granular::{self, Beads, ChainOutcome, NoRows};
use hertz_cradle::engine::{Overrides, Solver};
use hertz_cradle::scene::{Method, Precision, Scene};
use std::time::Instant;

fn solve(text: &str, method: Option<Method>, tol: Option<f64>) -> (Beads, ChainOutcome, f64) {
    solve_in(text, method, tol, Precision::F64)
}

fn solve_in(
    text: &str,
    method: Option<Method>,
    tol: Option<f64>,
    precision: Precision,
) -> (Beads, ChainOutcome, f64) {
    let s = Scene::from_toml_str("bench", text).unwrap();
    let b = Beads::from_scene(&s);
    let o = Overrides {
        method,
        tolerance: tol,
        precision: Some(precision),
        ..Default::default()
    };
    let plan = granular::plan(&b, &Solver::resolve(&s, &o).unwrap(), None);
    let t = Instant::now();
    let out = granular::run(&b, &plan, &mut NoRows);
    (b, out, t.elapsed().as_secs_f64())
}

/// The error of `o` against `r`: the probes' peak times (relative to the
/// run time) and peak velocities and every bead's final velocity (relative
/// to `v`); a probe the pulse never reached in `r` is left out.
fn chain_error(o: &ChainOutcome, r: &ChainOutcome, v: f64) -> f64 {
    let mut e = 0.0f64;
    for (p, q) in o.probes.iter().zip(&r.probes) {
        if q.arrival.is_finite() {
            e = e.max((p.arrival - q.arrival).abs() / r.t_end);
            e = e.max((p.peak_velocity - q.peak_velocity).abs() / v);
        }
    }
    for (a, c) in o.v.iter().zip(&r.v) {
        e = e.max((a - c).abs() / v);
    }
    e
}

fn struck(n: usize, v: f64, extra: &str) -> String {
    format!(
        "balls = {n}\nradius = 0.005\n[launch]\nballs = 1\nvelocity = {v}\n[probes]\nbeads = [{}, {}]\n{extra}",
        n / 4,
        3 * n / 4
    )
}

fn main() {
    println!("## Solitary wave (uniform steel chain, R = 5 mm, 200 beads, struck at bead 0; tolerance 1e-9)\n");
    println!("| striker v (m/s) | v_m (m/s) | v_m / v | V measured (m/s) | V Nesterenko (m/s) | deviation | V / v_m^(1/5) | FWHM (beads) |");
    println!("|---|---|---|---|---|---|---|---|");
    for v in [1e-3, 1e-2, 1e-1, 1.0] {
        let (b, o, _) = solve(&struck(200, v, ""), None, Some(1e-9));
        let vm = o.probes[1].peak_velocity;
        let th = granular::nesterenko_speed(b.k[1], b.mass[0], b.spacing[0], vm);
        println!(
            "| {v:e} | {vm:.6e} | {:.6} | {:.4} | {th:.4} | {:+.3}% | {:.6} | {:.3} |",
            vm / v,
            o.pulse_speed,
            100.0 * (o.pulse_speed / th - 1.0),
            o.pulse_speed / vm.powf(0.2),
            o.pulse_width
        );
    }
    println!("\n## Linear sound speed (400 beads, both walls, pulse 0.01 N × 20 µs at bead 0; tolerance 1e-8)\n");
    println!("| F0 (N) | c0 = a·√(K/m) (m/s) | pulse speed (m/s) | deviation |");
    println!("|---|---|---|---|");
    for f0 in [1.0, 10.0, 100.0] {
        let text = format!("balls = 400\nradius = 0.005\n[walls]\nleft = true\nright = true\nprecompression = {f0}\n[pulse]\nbead = 0\nforce = 0.01\nduration = 2e-5\n[probes]\nbeads = [100, 300]\n");
        let (b, o, _) = solve(&text, None, Some(1e-8));
        let kk = 1.5 * b.k[1].powf(2.0 / 3.0) * f64::powf(f0, 1.0 / 3.0);
        let c0 = b.spacing[0] * (kk / b.mass[0]).sqrt();
        println!(
            "| {f0} | {c0:.4} | {:.4} | {:+.3}% |",
            o.pulse_speed,
            100.0 * (o.pulse_speed / c0 - 1.0)
        );
    }

    let n = 1000;
    let text = struck(n, 0.1, "[stop]\nduration = 0.021\n");
    let (_, r, tr) = solve(&text, Some(Method::Yoshida4), Some(1e-10));
    println!("\n## Work-precision: 1,000 beads struck at 0.1 m/s, run 21 ms (the wave at bead ~890), one thread\n");
    println!("Reference: yoshida4 at tolerance 1e-10 ({} steps, {tr:.1} s). Error = the largest of the probes' (250, 750) peak times / run time and peak velocities / v, and every bead's final velocity / v.\n", r.steps);
    println!("| method | tolerance | error | steps | time (s) | bead-steps/s (all beads) |");
    println!("|---|---|---|---|---|---|");
    let error = |o: &ChainOutcome, r: &ChainOutcome| chain_error(o, r, 0.1);
    let mut f64_runs = vec![];
    for m in [Method::Verlet, Method::Yoshida4, Method::KahanLi6] {
        for tol in [1e-4, 1e-6, 1e-8] {
            if m == Method::Verlet && tol < 1e-6 {
                continue;
            }
            let (_, o, secs) = solve(&text, Some(m), Some(tol));
            println!(
                "| {} | {tol:e} | {:.2e} | {} | {secs:.3} | {:.3e} |",
                m.name(),
                error(&o, &r),
                o.steps,
                (o.steps * n as u64) as f64 / secs
            );
            if m == Method::KahanLi6 && tol < 1e-4 {
                f64_runs.push((tol, o, secs));
            }
        }
    }
    println!("\n## The same chain in df64 (pairs of f32, what a GPU without fast f64 runs; here on the CPU, one thread)\n");
    println!("| method | tolerance | error | steps | time (s) | time / f64's | largest difference from f64's outcome |");
    println!("|---|---|---|---|---|---|---|");
    for (tol, f, fsecs) in &f64_runs {
        let (_, o, secs) = solve_in(&text, Some(Method::KahanLi6), Some(*tol), Precision::Df64);
        println!(
            "| kahanli6 | {tol:e} | {:.2e} | {} | {secs:.3} | {:.1} | {:.1e} |",
            error(&o, &r),
            o.steps,
            secs / fsecs,
            error(&o, f)
        );
    }

    println!("\n## The tolerance on chains unlike the fit's (struck; against kahanli6 at a quarter of its step at tolerance 1e-12)\n");
    println!("Error = the largest of the probes' peak times / run time and peak velocities / v, and every bead's final velocity / v.\n");
    println!("| chain | method | tolerance | error | h | steps | regions a step |");
    println!("|---|---|---|---|---|---|---|");
    let others = [
        ("200-bead dimer (R 5 / 3.5 mm), wall after the last, 0.2 m/s, 3 ms", "balls = 200\nradius = 0.005\n[walls]\nright = true\n[pattern]\nradius = [0.005, 0.0035]\n[launch]\nballs = 1\nvelocity = 0.2\n[probes]\nbeads = [20, 150]\n[stop]\nduration = 3e-3\n", 0.2),
        ("300 beads tapered by 0.2% a bead, 4 ms", "balls = 300\nradius = 0.005\n[taper]\nratio = 0.002\n[launch]\nballs = 1\nvelocity = 0.1\n[probes]\nbeads = [50, 250]\n[stop]\nduration = 4e-3\n", 0.1),
        ("100 beads, wall after the last: the wave reflected, 5 ms", "balls = 100\nradius = 0.005\n[walls]\nright = true\n[launch]\nballs = 1\nvelocity = 0.1\n[probes]\nbeads = [20, 80]\n[stop]\nduration = 5e-3\n", 0.1),
        ("200 beads, a 1 g impurity at bead 100, 3 ms", "balls = 200\nradius = 0.005\n[impurity]\nbeads = [100]\nmass = 1e-3\n[launch]\nballs = 1\nvelocity = 0.1\n[probes]\nbeads = [50, 150]\n[stop]\nduration = 3e-3\n", 0.1),
    ];
    for (name, text, v) in others {
        let (b, tight, _) = solve(text, None, Some(1e-12));
        let (_, r, _) = solve(
            &format!("{text}[solver]\ndt = {:e}\n", tight.dt / 4.0),
            None,
            None,
        );
        for m in [Method::KahanLi6, Method::Suzuki4] {
            for tol in [1e-4, 1e-6, 1e-8, 1e-10] {
                let (_, o, _) = solve(text, Some(m), Some(tol));
                println!(
                    "| {name} | {} | {tol:e} | {:.2e} | t_s/{:.0} | {} | {:.3} |",
                    m.name(),
                    chain_error(&o, &r, v),
                    b.time_scale() / o.dt,
                    o.steps,
                    o.regions as f64 / o.steps as f64
                );
            }
        }
    }

    println!("\n## Cost per bead-step (whole chain moving: precompressed, a pulse at bead 0 and a striker at the far end; kahanli6, 20,000 steps)\n");
    println!("| beads | step | local refinement | regions a step | time (s) | ns per bead-step | relative to 100 |");
    println!("|---|---|---|---|---|---|---|");
    let chain = |n: usize, dt: f64| {
        let mut v = vec!["0.0".to_string(); n];
        v[n - 1] = "-0.01".into();
        format!("balls = {n}\nradius = 0.005\nvelocity = [{}]\n[walls]\nleft = true\nright = true\nprecompression = 10.0\n[pulse]\nbead = 0\nforce = 1.0\nduration = 1e-5\n[solver]\ndt = {dt:e}\n[stop]\nduration = {:e}\n", v.join(","), 2e4 * dt)
    };
    // The given step, and one of t_s/100 (the refinement on: REFINE_FROM).
    let ts =
        Beads::from_scene(&Scene::from_toml_str("bench", &chain(100, 5e-8)).unwrap()).time_scale();
    for (label, dt) in [("5e-8 s", 5e-8), ("t_s/100", ts / 100.0)] {
        let mut base = 0.0;
        for n in [100, 1000, 10000] {
            let (_, o, secs) = solve(&chain(n, dt), None, None);
            let ns = secs * 1e9 / (o.steps as f64 * n as f64);
            if n == 100 {
                base = ns;
            }
            let on = if dt <= ts / granular::REFINE_FROM {
                "on"
            } else {
                "off"
            };
            println!(
                "| {n} | {label} | {on} | {:.3} | {secs:.3} | {ns:.2} | {:.2} |",
                o.regions as f64 / o.steps as f64,
                ns / base
            );
        }
    }
}
