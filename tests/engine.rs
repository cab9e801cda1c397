//! Physics of the CPU engine against exact results (SPEC §6). Every assertion
//! here fails if the contact law, the integrator or the bookkeeping is wrong.

use hertz_cradle::engine::contact::{contact_time, hertz_stiffness, max_overlap};
use hertz_cradle::engine::{
    simulate_chain, Chain, Outcome, Overrides, Silent, Solver, Status, StepRule,
};
use hertz_cradle::scene::{Precision, Scene};

fn scene(text: &str) -> Scene {
    Scene::from_toml_str("test", text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn solve(s: &Scene, step: Option<StepRule>, precision: Precision) -> Outcome {
    let mut solver = Solver::resolve(
        s,
        &Overrides {
            precision: Some(precision),
            ..Default::default()
        },
    )
    .unwrap();
    if let Some(step) = step {
        solver.step = step;
    }
    simulate_chain(&Chain::from_scene(s).unwrap(), &solver, &mut Silent)
}

fn run(text: &str) -> Outcome {
    solve(&scene(text), None, Precision::F64)
}

/// max_i |v_i − want_i·v_in| / v_in
fn err(o: &Outcome, want: &[f64], v_in: f64) -> f64 {
    assert_eq!(o.v.len(), want.len());
    o.v.iter()
        .zip(want)
        .map(|(v, w)| (v / v_in - w).abs())
        .fold(0.0, f64::max)
}

fn steel_mass() -> f64 {
    7850.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.0125f64.powi(3)
}

#[test]
fn two_equal_balls_exchange_velocities() {
    for v in [0.01, 1.0, 7.0] {
        let o = run(&format!("balls = 2\nvelocity = [{v}, 0.0]"));
        assert_eq!(o.status, Status::Ok);
        assert!(err(&o, &[0.0, 1.0], v) < 1e-9, "{:?}", o.v);
        assert_eq!(o.ejected, 1);
    }
}

#[test]
fn mass_ratio_one_to_two() {
    let m = steel_mass();
    let o = run(&format!(
        "balls = 2\nmass = [{m}, {}]\nvelocity = [1.0, 0.0]",
        2.0 * m
    ));
    assert!(err(&o, &[-1.0 / 3.0, 2.0 / 3.0], 1.0) < 1e-9, "{:?}", o.v);
}

#[test]
fn glued_pair_into_one_ball() {
    let o = run("balls = 3\nglue = \"=-\"\nvelocity = [2.0, 2.0, 0.0]");
    assert!(
        err(&o, &[1.0 / 3.0, 1.0 / 3.0, 4.0 / 3.0], 2.0) < 1e-9,
        "{:?}",
        o.v
    );
    assert_eq!(o.v[0], o.v[1], "glued balls repeat their body's velocity");
}

#[test]
fn two_ball_contact_time_and_overlap_match_hertz() {
    let s = scene("balls = 2\nvelocity = [1.0, 0.0]");
    let m = s.mass[0];
    let k = hertz_stiffness(0.0125, 200e9, 0.3, 0.0125, 200e9, 0.3);
    let (tc, dmax) = (contact_time(m / 2.0, k, 1.0), max_overlap(m / 2.0, k, 1.0));
    // SPEC §6 numbers at 1 m/s
    assert!((tc / 7.6687e-5 - 1.0).abs() < 1e-4, "{tc}");
    assert!((dmax / 2.6055e-5 - 1.0).abs() < 1e-4, "{dmax}");
    let o = solve(&s, Some(StepRule::Dt(tc / 20_000.0)), Precision::F64);
    let duration = o.t_release - o.t_contact;
    assert!(
        (duration / tc - 1.0).abs() < 1e-4,
        "duration {duration} vs {tc}"
    );
    assert!(
        (o.max_overlap_m / dmax - 1.0).abs() < 1e-4,
        "overlap {} vs {dmax}",
        o.max_overlap_m
    );
}

const ONE_INTO_FOUR: [f64; 5] = [-0.07109, -0.03027, -0.01446, 0.12704, 0.98878];

#[test]
fn one_ball_into_four_matches_reference_at_default_settings() {
    let o = run("balls = 5\nvelocity = [1.0, 0, 0, 0, 0]");
    // SPEC values carry 5 decimals: compare to within their rounding + 1e-5.
    assert!(err(&o, &ONE_INTO_FOUR, 1.0) < 0.5e-5 + 1e-5, "{:?}", o.v);
    assert_eq!(o.ejected, 1);
    assert!(o.energy_error < 1e-6, "{}", o.energy_error);
}

#[test]
fn wide_gaps_give_hard_sphere_answers() {
    let o = run("balls = 5\ngap = 1e-4\nvelocity = [1.0, 0, 0, 0, 0]");
    assert!(err(&o, &[0.0, 0.0, 0.0, 0.0, 1.0], 1.0) < 1e-9, "{:?}", o.v);
    let o = run("balls = 5\ngap = 1e-4\nglue = \"=---\"\nvelocity = [1.0, 1.0, 0, 0, 0]\n[solver]\ntolerance = 1e-8");
    let want = [1.0 / 27.0, 1.0 / 27.0, 4.0 / 27.0, 4.0 / 9.0, 4.0 / 3.0];
    assert!(err(&o, &want, 1.0) < 1e-9, "{:?}", o.v);
}

#[test]
fn free_flight_costs_no_steps() {
    // Two well-separated impacts cost the same steps whatever the gap width.
    let a = run("balls = 3\ngap = 1e-3\nvelocity = [1e-3, 0, 0]");
    let b = run("balls = 3\ngap = 1e-4\nvelocity = [1e-3, 0, 0]");
    assert_eq!(a.status, Status::Ok);
    assert_eq!(a.steps, b.steps);
    assert!(
        (a.t_contact - 1.0).abs() < 1e-12,
        "first onset at gap/v = 1 s, got {}",
        a.t_contact
    );
    // Nothing approaching: settled at once.
    let c = run("balls = 3\nvelocity = [-1.0, 0, 1.0]");
    assert_eq!((c.steps, c.status), (0, Status::Ok));
    assert_eq!(c.v, vec![-1.0, 0.0, 1.0]);
}

#[test]
fn touching_chain_outcome_scales_with_speed() {
    let base = run("balls = 5\nvelocity = [1.0, 0, 0, 0, 0]");
    for v in [0.01, 0.1, 3.0, 10.0] {
        let o = run(&format!("balls = 5\nvelocity = [{v}, 0, 0, 0, 0]"));
        let d =
            o.v.iter()
                .zip(&base.v)
                .map(|(a, b)| (a / v - b).abs())
                .fold(0.0, f64::max);
        assert!(d < 1e-10, "v = {v}: {d:e}");
    }
}

#[test]
fn mirrored_chain_gives_mirrored_outcome() {
    let m = steel_mass();
    let a = run(&format!(
        "balls = 4\nmass = [{m}, {}, {}, {m}]\ngap = [0, 3e-6, 1e-5]\nglue = \"-=-\"\nvelocity = [1.0, 0, 0, -0.3]",
        0.5 * m,
        0.5 * m
    ));
    let b = run(&format!(
        "balls = 4\nmass = [{m}, {}, {}, {m}]\ngap = [1e-5, 3e-6, 0]\nglue = \"-=-\"\nvelocity = [0.3, 0, 0, -1.0]",
        0.5 * m,
        0.5 * m
    ));
    for i in 0..4 {
        assert!(
            (a.v[i] + b.v[3 - i]).abs() < 1e-12,
            "{:?} vs {:?}",
            a.v,
            b.v
        );
    }
}

#[test]
fn verlet_converges_with_order_two() {
    // Light middle ball: a scene with several contacts opening and closing.
    let m = steel_mass();
    let s = scene(&format!(
        "balls = 5\nmass = [{m}, {m}, {}, {m}, {m}]\ngap = 2e-6\nvelocity = [1.0, 0, 0, 0, 0]",
        0.3 * m
    ));
    let tc = Chain::from_scene(&s).unwrap().time_scale().unwrap();
    let v = |div: f64| solve(&s, Some(StepRule::Dt(tc / div)), Precision::F64).v;
    let (a, b, c) = (v(100.0), v(200.0), v(400.0));
    let diff = |x: &[f64], y: &[f64]| {
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max)
    };
    let order = (diff(&a, &b) / diff(&b, &c)).log2();
    assert!(order >= 1.8, "observed order {order}");
    assert!(order <= 2.6, "observed order {order}: suspiciously high");
}

#[test]
fn f32_agrees_with_f64() {
    let s = scene("balls = 5\ngap = [0, 1e-6, 0, 4e-6]\nvelocity = [1.0, 1.0, 0, 0, 0]");
    let a = solve(&s, None, Precision::F64);
    let b = solve(&s, None, Precision::F32);
    assert_eq!(b.status, Status::Ok);
    assert!(err(&b, &a.v, 1.0) < 1e-5, "{:?} vs {:?}", a.v, b.v);
}

#[test]
fn too_large_a_step_is_flagged_not_reported() {
    let s = scene("balls = 5\nvelocity = [1.0, 0, 0, 0, 0]\n[solver]\ndt = 3e-5");
    let o = solve(&s, None, Precision::F64);
    assert_ne!(o.status, Status::Ok, "{o:?}");
}

#[test]
fn caps_give_non_ok_status() {
    let o = run("balls = 3\ngap = 1.0\nvelocity = [1.0, 0, 0]\n[stop]\nduration = 0.5");
    assert_eq!(o.status, Status::TimeCap);
    let o = run("balls = 5\nvelocity = [1.0, 0, 0, 0, 0]\n[stop]\nmax_steps = 10");
    assert_eq!(o.status, Status::StepCap);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    fn random_scene() -> impl Strategy<Value = String> {
        (2usize..8).prop_flat_map(|n| {
            (
                Just(n),
                prop::collection::vec(0.2f64..5.0, n),
                prop::collection::vec(prop_oneof![Just(0.0), 0.0f64..2e-5], n - 1),
                prop::collection::vec(any::<bool>(), n - 1),
                prop::collection::vec(-1.0f64..1.0, n),
            )
        })
        .prop_map(|(n, mf, gap, glue, mut v)| {
            let m = steel_mass();
            for i in 0..n - 1 {
                if glue[i] {
                    v[i + 1] = v[i];
                }
            }
            let mass: Vec<String> = mf.iter().map(|f| format!("{}", f * m)).collect();
            let gap: Vec<String> = gap.iter().map(|g| g.to_string()).collect();
            let glue: String = glue.iter().map(|&g| if g { '=' } else { '-' }).collect();
            let v: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            format!(
                "balls = {n}\nmass = [{}]\ngap = [{}]\nglue = \"{glue}\"\nvelocity = [{}]\n[solver]\ntolerance = 1e-4",
                mass.join(","),
                gap.join(","),
                v.join(",")
            )
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
        #[test]
        fn momentum_is_conserved_and_energy_error_small(text in random_scene()) {
            let o = run(&text);
            prop_assert_eq!(o.status, Status::Ok, "{}", text);
            prop_assert!(o.momentum_error <= 1e-12, "momentum {:e}\n{}", o.momentum_error, text);
            prop_assert!(o.energy_error <= 1e-3, "energy {:e}\n{}", o.energy_error, text);
        }
    }
}
