//! The cost of damping on chains (issue #45; results/chains.md, "Damping,
//! pistons, drives"): a 1,000-bead steel chain struck at one end (free, or
//! precompressed between walls), or precompressed with every bead moving
//! from the start (its window the whole chain, every contact closed and
//! moving: the damping's worst case per bead-step), at a fixed step,
//! undamped and with each kind of damping, the window the whole chain
//! (`run_with(.., whole = true)`: every bead stepped, so the time per
//! bead-step compares the step's own work, beads at rest ahead of the wave
//! included) and as a run windows it (the beads near the wave: what a user
//! waits for), with the mean window and the time per bead the run stepped
//! (the plan's `Tally`: damping costs more near the wave, where contacts
//! are closed, than ahead of it). Each damping in every substep (`[solver]
//! damping_split = "substeps"`) and at the steps' ends ("ends"; the
//! default "auto" picks the ends for every damping here: the dashpots and
//! the drag are weak on the chain's time scale, and e = 0.9 is above the
//! Hunt–Crossley threshold).
//! Best of 3 runs (or of the first argument's), one thread, the chain's
//! cases taking turns (round-robin), so that a slow spell of a shared
//! machine slows one run of each rather than one case's every run.
//!
//! The last two columns: the windowed run with `Plan::rest` = 0 (only beads
//! at exact rest wait: the window before 1e-30 of the velocity scale was
//! rest's, results/chains.md "Beads at rest to 1e-30").
//!
//! `cargo run --release --example damping_cost [runs] [filter]` (filter:
//! only the rows whose chain and damping, "chain: damping", contain it —
//! e.g. "precompressed 10 N: viscosity" — each still against its chain's
//! undamped run)

use hertz_cradle::engine::granular::{self, run::run_with, Beads, NoRows};
use hertz_cradle::engine::{Overrides, Solver, Tally};
use hertz_cradle::scene::Scene;
use std::time::Instant;

fn main() {
    let runs: usize = match std::env::args().nth(1) {
        None => 3,
        Some(a) => match a.parse() {
            Ok(n) if n > 0 => n,
            _ => {
                eprintln!("damping_cost: runs must be a positive integer, not {a:?}");
                std::process::exit(2);
            }
        },
    };
    let filter = std::env::args().nth(2).unwrap_or_default();
    // Every bead of the third chain moving from the start (its window the
    // whole chain, every contact closed and moving: the damping's worst
    // case per bead-step): speeds uniform in ±0.01 m/s from a fixed
    // xorshift, written out to 6 decimals.
    let mut x = 0x9e37_79b9_7f4a_7c15_u64;
    let speeds: Vec<String> = (0..1000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            format!(
                "{:.6}",
                ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
            )
        })
        .collect();
    let moving = format!("velocity = [{}]\n", speeds.join(", "));
    let base = |extra: &str, chain: usize| {
        // `extra`'s first line, if it names the split, goes in [solver].
        let (split, extra) = match extra.strip_prefix("damping_split") {
            Some(rest) => rest.split_once('\n').unwrap(),
            None => ("", extra),
        };
        let split = if split.is_empty() {
            String::new()
        } else {
            format!("damping_split{split}\n")
        };
        // Per-bead velocities are top-level keys, before any table.
        let walls = "[walls]\nleft = true\nright = true\nprecompression = 10.0\n";
        let launch = "[launch]\nballs = 1\nvelocity = 0.1\n";
        let (top, walls, launch) = match chain {
            0 => ("", "", launch),
            1 => ("", walls, launch),
            _ => (moving.as_str(), walls, ""),
        };
        format!(
            "balls = 1000\nradius = 0.005\n{top}{walls}{launch}[probes]\nbeads = [250, 750]\n\
             [solver]\ndt = 2e-7\n{split}[stop]\nduration = 4e-3\n{extra}"
        )
    };
    println!("| chain | damping | ns per bead-step (whole chain) | × undamped | run, windowed (s) | × undamped | mean window (beads) | ns per bead-step (window) | × undamped | run, window of exact rest (s) | its mean window |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let dampings = [
        ("none", ""),
        (
            "viscosity 0.5 N·s/m, in the substeps",
            "damping_split = \"substeps\"\n[damping]\nviscosity = 0.5\n",
        ),
        (
            "restitution 0.9, in the substeps",
            "damping_split = \"substeps\"\n[damping]\nrestitution = 0.9\n",
        ),
        (
            "air drag 10/s, in the substeps",
            "damping_split = \"substeps\"\n[damping]\nair_drag = 10.0\n",
        ),
        (
            "viscosity 0.5 N·s/m, at the ends",
            "damping_split = \"ends\"\n[damping]\nviscosity = 0.5\n",
        ),
        (
            "restitution 0.9, at the ends",
            "damping_split = \"ends\"\n[damping]\nrestitution = 0.9\n",
        ),
        (
            "air drag 10/s, at the ends",
            "damping_split = \"ends\"\n[damping]\nair_drag = 10.0\n",
        ),
    ];
    let chains = [
        "uncompressed",
        "precompressed 10 N",
        "precompressed 10 N, every bead moving",
    ];
    for (which, chain) in chains.into_iter().enumerate() {
        // The chain's runs: undamped first, then the dampings the filter
        // keeps.
        let cases: Vec<_> = dampings
            .iter()
            .filter(|(name, _)| *name == "none" || format!("{chain}: {name}").contains(&filter))
            .map(|&(name, extra)| {
                let s = Scene::from_toml_str("cost", &base(extra, which)).unwrap();
                let b = Beads::from_scene(&s);
                let solver = Solver::resolve(&s, &Overrides::default()).unwrap();
                let whole = granular::plan(&b, &solver, None);
                let mut windowed = granular::plan(&b, &solver, None);
                // The windowed runs' bead-steps, as the run counts them.
                let tally = Tally::new();
                windowed.tally = tally.clone();
                // The window as it was before `Plan::rest`: only beads at
                // exact rest wait.
                let mut exact = windowed.clone();
                exact.rest = 0.0;
                exact.tally = Tally::new();
                (name, b, [whole, windowed, exact], tally)
            })
            .collect();
        // Round-robin, best of `runs` each: a slow spell of the machine
        // slows every case's run in it, not one case's best.
        let mut best = vec![[(f64::INFINITY, 0u64); 3]; cases.len()];
        for _ in 0..runs {
            for (case, (_, b, plans, _)) in best.iter_mut().zip(&cases) {
                for (slot, (plan, w)) in case.iter_mut().zip(plans.iter().zip([true, false, false]))
                {
                    let t = Instant::now();
                    let o = run_with(b, plan, &mut NoRows, w);
                    let x = (t.elapsed().as_secs_f64(), o.steps);
                    if x.0 < slot.0 {
                        *slot = x;
                    }
                }
            }
        }
        let mut first = None;
        for ((name, b, plans, tally), [(tw, steps), (tr, _), (te, _)]) in cases.iter().zip(best) {
            let stepped = tally.get().unwrap_or(0) as f64 / runs as f64;
            let stepped_exact = plans[2].tally.get().unwrap_or(0) as f64 / runs as f64;
            let ns = tw / (steps as f64 * b.n as f64) * 1e9;
            let nw = tr / stepped * 1e9;
            let (ns0, tr0, nw0) = *first.get_or_insert((ns, tr, nw));
            println!(
                "| {chain} | {name} | {ns:.2} | {:.2} | {tr:.3} | {:.1} | {:.0} | {nw:.2} | {:.2} | {te:.3} | {:.0} |",
                ns / ns0,
                tr / tr0,
                stepped / steps as f64,
                nw / nw0,
                stepped_exact / steps as f64,
            );
        }
    }
}
