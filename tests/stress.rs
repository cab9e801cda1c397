//! Numerical stability at the edges of the parameter space (the stress issue):
//! mass ratios 1e-3…1e3, launch speeds 1e-4…10 m/s, Young's moduli 1e7…1e12 Pa,
//! gaps 0…1 mm, chains of 2…64 balls with glue. Every scene must come out `ok`
//! (conservation within bounds) or carry a status that says why not; no NaN
//! ever reaches an output. Plus properties: mirror symmetry, speed scaling, a
//! glued group ≡ one ball, independence of batching.

use hertz_cradle::backend::cpu::Cpu;
use hertz_cradle::backend::{Backend, Job};
use hertz_cradle::engine::{simulate_chain, Chain, Outcome, Overrides, Silent, Solver, Status};
use hertz_cradle::scene::{Precision, Scene};
use proptest::prelude::*;

mod common;
use common::STEEL_MASS as STEEL_M;

fn scene(text: &str) -> Scene {
    Scene::from_toml_str("stress", text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn job(s: &Scene, precision: Precision, tolerance: f64) -> Job {
    let o = Overrides {
        precision: Some(precision),
        tolerance: Some(tolerance),
        ..Default::default()
    };
    Job::Run {
        chain: Chain::from_scene(s).unwrap(),
        solver: Solver::resolve(s, &o).unwrap(),
    }
}

/// A deterministic sample of the envelope, each scene with its region label.
fn envelope() -> Vec<(String, Scene)> {
    let mut rnd = common::uniform(0x9e37_79b9_7f4a_7c15);
    let log = |r: f64, a: f64, b: f64| (a.ln() + r * (b.ln() - a.ln())).exp();
    let mut out = Vec::new();
    for i in 0..240 {
        let n = [2, 3, 5, 8, 16, 64][i % 6];
        let ratio = log(rnd(), 1e-3, 1e3);
        let speed = log(rnd(), 1e-4, 10.0);
        let young = log(rnd(), 1e7, 1e12);
        let gap = if rnd() < 0.3 {
            0.0
        } else {
            log(rnd(), 1e-7, 1e-3)
        };
        let glue: String = (0..n - 1)
            .map(|j| if j > 0 && rnd() < 0.15 { '=' } else { '-' })
            .collect();
        // ball 1 (or its glued group) carries the mass ratio
        let mass: Vec<String> = (0..n)
            .map(|j| format!("{}", if j == 1 { STEEL_M * ratio } else { STEEL_M }))
            .collect();
        let text = format!(
            "balls = {n}\nmass = [{}]\nyoung_modulus = {young}\ngap = {gap}\nglue = \"{glue}\"\n[launch]\nballs = 1\nvelocity = {speed}",
            mass.join(",")
        );
        let region = format!(
            "N={n:<2} ratio {} speed {} E {}",
            if ratio < 0.1 {
                "<0.1 "
            } else if ratio > 10.0 {
                ">10  "
            } else {
                "~1   "
            },
            if speed < 1e-2 {
                "slow"
            } else if speed > 1.0 {
                "fast"
            } else {
                "mid "
            },
            if young < 1e9 { "soft" } else { "hard" }
        );
        out.push((region, scene(&text)));
    }
    out
}

/// `momentum_bound`: 1e-9 in f64 (the stress issue), 1e-5 in f32.
fn check_outcome(o: &Outcome, what: &str, momentum_bound: f64) {
    if o.status == Status::Ok {
        for x in
            o.v.iter()
                .chain([&o.energy_error, &o.momentum_error, &o.max_overlap_m])
        {
            assert!(
                x.is_finite(),
                "{what}: non-finite output in an ok row: {o:?}"
            );
        }
        assert!(
            o.momentum_error <= momentum_bound,
            "{what}: momentum error {:e}: {o:?}",
            o.momentum_error
        );
        assert!(
            o.energy_error <= 1e-3,
            "{what}: energy error {:e}",
            o.energy_error
        );
    } else {
        // a non-ok status must say why: caps, non-finite, energy, overlap validity
        assert!(
            matches!(
                o.status,
                Status::StepCap
                    | Status::TimeCap
                    | Status::NonFinite
                    | Status::EnergyError
                    | Status::OverlapInvalid
            ),
            "{what}: {o:?}"
        );
    }
}

#[test]
fn envelope_is_ok_or_says_why_and_f32_follows_f64() {
    let scenes = envelope();
    let jobs64: Vec<Job> = scenes
        .iter()
        .map(|(_, s)| job(s, Precision::F64, 1e-6))
        .collect();
    let jobs32: Vec<Job> = scenes
        .iter()
        .map(|(_, s)| job(s, Precision::F32, 1e-4))
        .collect();
    let (o64, o32) = (Cpu.run(&jobs64).unwrap(), Cpu.run(&jobs32).unwrap());
    let mut ok = 0;
    let mut worst_by_region: std::collections::BTreeMap<String, f64> = Default::default();
    for (((region, s), a), b) in scenes.iter().zip(&o64).zip(&o32) {
        check_outcome(a, &format!("f64 {region} {s:?}"), 1e-9);
        check_outcome(b, &format!("f32 {region} {s:?}"), 1e-5);
        if a.status == Status::Ok {
            ok += 1;
        } else {
            eprintln!("not ok: {} {region} ratio {:.1e} v_in {:.1e} E {:.1e} steps {} t {:.3e} v {:?} gap {:e} glue {:?}", a.status, s.mass[1] / s.mass[0], s.v_in(), s.young_modulus[0], a.steps, a.t_end, a.v, s.gap[0], s.glue);
        }
        if a.status == Status::Ok && b.status == Status::Ok {
            let d =
                a.v.iter()
                    .zip(&b.v)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max)
                    / s.v_in();
            let w = worst_by_region.entry(region.clone()).or_default();
            *w = w.max(d);
        }
    }
    for (region, d) in &worst_by_region {
        eprintln!("f32 vs f64  {region}: {d:.1e}");
    }
    let frac = ok as f64 / scenes.len() as f64;
    eprintln!("ok: {ok}/{} = {:.1}%", scenes.len(), 100.0 * frac);
    assert!(frac >= 0.95, "only {:.1}% ok", 100.0 * frac);
}

#[test]
fn long_pendulum_run_of_ten_thousand_contacts_stays_sound() {
    // A 5-ball cradle on 5 cm strings swinging for 270 s: about 600 swings and
    // 12,000 contacts, in f64 and f32 (tolerance 1e-4, split over the events).
    let text = "balls = 5\n[launch]\nballs = 1\nheight = 0.005\n[pendulum]\nlength = 0.05\n[stop]\nduration = 270.0";
    let s = scene(text);
    let jobs: Vec<Job> = [Precision::F64, Precision::F32]
        .into_iter()
        .map(|p| job(&s, p, 1e-4))
        .collect();
    let out = Cpu.run(&jobs).unwrap();
    for (o, p) in out.iter().zip(["f64", "f32"]) {
        assert_eq!(o.status, Status::Ok, "{p}: {o:?}");
        assert!(o.contacts >= 10_000, "{p}: {} contacts", o.contacts);
        assert!(o.v.iter().chain(&o.x).all(|x| x.is_finite()), "{p}: {o:?}");
        // no damping: energy conserved over 10^4 contacts and 600 swings
        assert!(
            o.energy_error <= 1e-5,
            "{p}: energy error {:e}",
            o.energy_error
        );
        eprintln!(
            "long pendulum {p}: {} contacts, {} steps, energy error {:.1e}",
            o.contacts, o.steps, o.energy_error
        );
    }
    eprintln!(
        "long pendulum f32 vs f64: energy left differs by {:.1e}, x_4 by {:.1e} m",
        (out[1].energy_left - out[0].energy_left).abs(),
        (out[1].x[4] - out[0].x[4]).abs()
    );
}

#[test]
fn slow_free_flight_costs_no_steps() {
    // A ball crossing 1 mm at 1e-4 m/s: ten seconds of flight, zero steps.
    let wide = simulate(&scene("balls = 2\ngap = 1e-3\nvelocity = [1e-4, 0]"));
    let touching = simulate(&scene("balls = 2\nvelocity = [1e-4, 0]"));
    assert_eq!(wide.status, Status::Ok);
    assert_eq!(wide.steps, touching.steps);
    assert!((wide.t_contact - 10.0).abs() < 1e-9, "{}", wide.t_contact);
}

#[test]
fn a_user_step_too_large_is_flagged() {
    for dt in [1e-5, 3e-5, 1e-4] {
        let o = simulate(&scene(&format!(
            "balls = 5\nvelocity = [1.0, 0, 0, 0, 0]\n[solver]\nmethod = \"verlet\"\ndt = {dt}"
        )));
        assert_ne!(o.status, Status::Ok, "dt = {dt}: {o:?}");
    }
}

fn simulate(s: &Scene) -> Outcome {
    let solver = Solver::resolve(s, &Overrides::default()).unwrap();
    simulate_chain(&Chain::from_scene(s).unwrap(), &solver, &mut Silent)
}

fn chain_text(masses: &[f64], gaps: &[f64], glue: &str, v: &[f64]) -> String {
    let j = |x: &[f64]| {
        x.iter()
            .map(|y| y.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    format!(
        "balls = {}\nmass = [{}]\ngap = [{}]\nglue = \"{glue}\"\nvelocity = [{}]",
        masses.len(),
        j(masses),
        j(gaps),
        j(v)
    )
}

fn arb_chain() -> impl Strategy<Value = (Vec<f64>, Vec<f64>, Vec<f64>)> {
    (2usize..7).prop_flat_map(|n| {
        (
            prop::collection::vec(0.1f64..10.0, n),
            prop::collection::vec(prop_oneof![Just(0.0), 0.0f64..2e-5], n - 1),
            prop::collection::vec(-1.0f64..1.0, n),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn mirrored_chains_give_mirrored_outcomes((m, g, v) in arb_chain()) {
        let masses: Vec<f64> = m.iter().map(|x| x * STEEL_M).collect();
        let glue = "-".repeat(m.len() - 1);
        let a = simulate(&scene(&chain_text(&masses, &g, &glue, &v)));
        let rev = |x: &[f64]| x.iter().rev().copied().collect::<Vec<_>>();
        let vr: Vec<f64> = v.iter().rev().map(|x| -x).collect();
        let b = simulate(&scene(&chain_text(&rev(&masses), &rev(&g), &glue, &vr)));
        prop_assert_eq!(a.status, b.status);
        let vin = v.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        for i in 0..m.len() {
            // both are within the default tolerance (1e-6) of the truth
            prop_assert!((a.v[i] + b.v[m.len() - 1 - i]).abs() <= 2e-6 * vin, "{:?} vs {:?}", a.v, b.v);
        }
    }

    #[test]
    fn touching_chains_scale_with_speed((m, _g, v) in arb_chain(), scale in 0.01f64..10.0) {
        let masses: Vec<f64> = m.iter().map(|x| x * STEEL_M).collect();
        let zeros = vec![0.0; m.len() - 1];
        let glue = "-".repeat(m.len() - 1);
        let a = simulate(&scene(&chain_text(&masses, &zeros, &glue, &v)));
        let vs: Vec<f64> = v.iter().map(|x| x * scale).collect();
        let b = simulate(&scene(&chain_text(&masses, &zeros, &glue, &vs)));
        let vin = v.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        for (x, y) in a.v.iter().zip(&b.v) {
            prop_assert!((x - y / scale).abs() <= 1e-9 * vin, "{:?} vs {:?}", a.v, b.v);
        }
    }

    #[test]
    fn a_glued_pair_is_one_ball_of_the_summed_mass((m, g, v) in arb_chain()) {
        // Glue balls 0 and 1 (same speed) ≡ a single ball of their summed mass;
        // the contact with ball 2 uses ball 1's radius, which is the default here.
        prop_assume!(m.len() >= 3);
        let masses: Vec<f64> = m.iter().map(|x| x * STEEL_M).collect();
        let mut vv = v.clone();
        vv[1] = vv[0];
        let glue = format!("={}", "-".repeat(m.len() - 2));
        let a = simulate(&scene(&chain_text(&masses, &g, &glue, &vv)));
        let mut one = masses[1..].to_vec();
        one[0] += masses[0];
        let b = simulate(&scene(&chain_text(&one, &g[1..], &"-".repeat(m.len() - 2), &vv[1..])));
        prop_assert_eq!(a.status, b.status);
        prop_assert_eq!(a.v[0], a.v[1]);
        for i in 1..m.len() {
            prop_assert!((a.v[i] - b.v[i - 1]).abs() <= 1e-12, "{:?} vs {:?}", a.v, b.v);
        }
    }

    #[test]
    fn outcomes_do_not_depend_on_batching((m, g, v) in arb_chain(), split in 1usize..5) {
        let masses: Vec<f64> = m.iter().map(|x| x * STEEL_M).collect();
        let glue = "-".repeat(m.len() - 1);
        let s = scene(&chain_text(&masses, &g, &glue, &v));
        let jobs: Vec<Job> = (0..5).map(|_| job(&s, Precision::F64, 1e-6)).collect();
        let whole = Cpu.run(&jobs).unwrap();
        let mut parts = Cpu.run(&jobs[..split]).unwrap();
        parts.extend(Cpu.run(&jobs[split..]).unwrap());
        // Debug text: NaN fields (no contact times) compare unequal as floats
        prop_assert_eq!(format!("{whole:?}"), format!("{parts:?}"));
    }
}
