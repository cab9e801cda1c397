//! The contact law — the one place on the Rust side that says how two balls
//! push on each other. Its WGSL twin is `hertz_force` in `shaders/cradle/kernels.wgsl`.
//!
//! Hertz (docs/SPEC.md §2): overlap δ = x_i − x_{i+1} − g_i; force F = k·δ^{3/2} for δ > 0,
//! zero otherwise (no tension), with k = (4/3)·E*·√R*.
//!
//! Damping (`[damping] restitution = e`): the Hunt–Crossley law
//! F = k·δ^{3/2}·(1 + χ·δ̇), clamped at 0 (never tension), with χ = a(e)/v_imp
//! set from the closing speed v_imp at each contact's onset. In units where
//! the impact speed is 1 the law has a single parameter a = χ·v_imp, so a(e) is
//! found once per e by solving the dimensionless two-body impact
//! ([`hunt_crossley_a`]): a two-body impact then rebounds with exactly e at
//! every speed — unlike closed-form approximations of χ, which drift from e
//! at low e.

use super::real::Real;

/// Effective modulus E* of two materials: 1/E* = (1−ν₁²)/E₁ + (1−ν₂²)/E₂ (Pa).
pub fn effective_modulus(e1: f64, nu1: f64, e2: f64, nu2: f64) -> f64 {
    1.0 / ((1.0 - nu1 * nu1) / e1 + (1.0 - nu2 * nu2) / e2)
}

/// Effective radius R*: 1/R* = 1/R₁ + 1/R₂ (m).
pub fn effective_radius(r1: f64, r2: f64) -> f64 {
    1.0 / (1.0 / r1 + 1.0 / r2)
}

/// Hertz stiffness k = (4/3)·E*·√R* (N/m^{3/2}).
pub fn hertz_stiffness(r1: f64, e1: f64, nu1: f64, r2: f64, e2: f64, nu2: f64) -> f64 {
    4.0 / 3.0 * effective_modulus(e1, nu1, e2, nu2) * effective_radius(r1, r2).sqrt()
}

/// Contact force for overlap `d` (N). δ^{3/2} is written δ·√δ, never `powf`
/// (on some GPU drivers f64 `pow` silently returns garbage; keep the twins equal).
#[inline(always)]
pub fn hertz_force<R: Real>(k: R, d: R) -> R {
    if d > R::zero() {
        k * d * d.sqrt()
    } else {
        R::zero()
    }
}

/// Damped contact force (N): Hertz times (1 + χ·r), never negative; `r` is the
/// closing speed δ̇ (m/s), χ the Hunt–Crossley coefficient (s/m, 0: elastic).
#[inline(always)]
pub fn contact_force<R: Real>(k: R, d: R, chi: R, r: R) -> R {
    hertz_force(k, d) * (R::one() + chi * r).max(R::zero())
}

/// Restitution of the dimensionless Hunt–Crossley impact ξ'' = −ξ^{3/2}·(1 + a·ξ')⁺,
/// ξ(0) = 0, ξ'(0) = 1: the separation speed −ξ' when ξ returns to 0
/// (classical RK4; the step is fine enough for 1e-7).
pub fn hunt_crossley_restitution(a: f64) -> f64 {
    let acc = |x: f64, v: f64| -> f64 {
        if x > 0.0 {
            -x * x.sqrt() * (1.0 + a * v).max(0.0)
        } else {
            0.0
        }
    };
    let dt = 1e-3;
    let (mut x, mut v) = (0.0f64, 1.0f64);
    for _ in 0..100_000_000u64 {
        let (k1x, k1v) = (v, acc(x, v));
        let (k2x, k2v) = (
            v + 0.5 * dt * k1v,
            acc(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v),
        );
        let (k3x, k3v) = (
            v + 0.5 * dt * k2v,
            acc(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v),
        );
        let (k4x, k4v) = (v + dt * k3v, acc(x + dt * k3x, v + dt * k3v));
        let x1 = x + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        let v1 = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        if x1 <= 0.0 && v1 < 0.0 {
            // Locate the return to ξ = 0 inside the step.
            let w = x / (x - x1);
            return -(v + w * (v1 - v));
        }
        if (0.0..1e-12).contains(&v1) && x1 <= x {
            return 0.0; // stuck: everything dissipated
        }
        x = x1;
        v = v1;
    }
    0.0
}

/// The Hunt–Crossley parameter a = χ·v_imp for restitution `e` in (0, 1]:
/// the inverse of [`hunt_crossley_restitution`], by bisection, cached per e
/// (a sweep uses few distinct values).
pub fn hunt_crossley_a(e: f64) -> f64 {
    use std::sync::Mutex;
    static CACHE: Mutex<Vec<(u64, f64)>> = Mutex::new(Vec::new());
    if e >= 1.0 {
        return 0.0;
    }
    if let Some(&(_, a)) = CACHE
        .lock()
        .unwrap()
        .iter()
        .find(|(b, _)| *b == e.to_bits())
    {
        return a;
    }
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    while hunt_crossley_restitution(hi) > e && hi < 1e6 {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if hunt_crossley_restitution(mid) > e {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-10 * hi {
            break;
        }
    }
    let a = 0.5 * (lo + hi);
    CACHE.lock().unwrap().push((e.to_bits(), a));
    a
}

/// Elastic energy stored in a contact, ∫F dδ = (2/5)·k·δ^{5/2} (J).
pub fn hertz_energy(k: f64, d: f64) -> f64 {
    if d > 0.0 {
        0.4 * k * d * d * d.sqrt()
    } else {
        0.0
    }
}

/// The constant of the two-body Hertz contact time, t_c = C·(μ²/(k²v))^{1/5}:
/// C = 2·(5/4)^{2/5}·(2/5)·√π·Γ(2/5)/Γ(9/10) ≈ 3.2180655.
pub const CONTACT_TIME_CONST: f64 = 3.218_065_459_719_043;

/// Duration of a two-body Hertz impact of reduced mass `mu` (kg) at approach
/// speed `v` (m/s) (docs/SPEC.md §6).
pub fn contact_time(mu: f64, k: f64, v: f64) -> f64 {
    CONTACT_TIME_CONST * (mu * mu / (k * k * v)).powf(0.2)
}

/// Largest overlap of a two-body Hertz impact: (5μv²/(4k))^{2/5} (m).
pub fn max_overlap(mu: f64, k: f64, v: f64) -> f64 {
    (5.0 * mu * v * v / (4.0 * k)).powf(0.4)
}

/// Coefficients (a, b) of an isolated two-body Hertz impact in closed form:
/// at approach speed u it lasts t_c = a/u^{1/5} and reaches δ_max =
/// b·u/u^{1/5} (s, m) — the contact time and peak overlap at 1 m/s. The
/// integrators take such an impact in one jump (`integrate`'s
/// `exact_impact`), so both get these from the host.
pub fn impact_coefficients(mu: f64, k: f64) -> (f64, f64) {
    (contact_time(mu, k, 1.0), max_overlap(mu, k, 1.0))
}

/// x^{1/5} for x > 0, from +, −, ×, ÷ only, the same operations as
/// `fifth_root` in the shader (SPIR-V has no f64 pow; f64 `pow` on some
/// drivers is garbage): x scaled by powers of 32 into [1, 32) (exact), a
/// quadratic first guess, five Newton steps (relative error < 1e-14 in f64).
#[inline(always)]
pub fn fifth_root<R: Real>(x: R) -> R {
    let (one, n32) = (R::one(), R::of(32.0));
    let (mut y, mut s) = (x, one);
    let mut n = 0;
    while y >= n32 && n < FIFTH_ROOT_SCALINGS {
        y = y / n32;
        s = s * R::of(2.0);
        n += 1;
    }
    while y < one && n < FIFTH_ROOT_SCALINGS {
        y = y * n32;
        s = s * R::of(0.5);
        n += 1;
    }
    let mut w = R::of(1.1) + y * (R::of(0.0542) - y * R::of(0.00086));
    for _ in 0..5 {
        let w2 = w * w;
        w = (R::of(4.0) * w + y / (w2 * w2)) * R::of(0.2);
    }
    w * s
}

/// Most scalings by 32 in [`fifth_root`]: enough for any speed from 1e-300
/// to 1e300 m/s; beyond, the root is wrong but finite (both twins alike).
pub const FIFTH_ROOT_SCALINGS: u32 = 200;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifth_root_is_accurate_over_every_speed_scale() {
        let mut x = 1.3e-14f64;
        while x < 1e15 {
            let r = fifth_root(x);
            assert!((r / x.powf(0.2) - 1.0).abs() < 1e-14, "{x}: {r}");
            let r32 = fifth_root(x as f32) as f64;
            assert!((r32 / x.powf(0.2) - 1.0).abs() < 1e-6, "{x}: {r32}");
            x *= 1.37;
        }
        for x in [1.0f64, 32.0, 1024.0, 1.0 / 32.0] {
            assert!((fifth_root(x) / x.powf(0.2) - 1.0).abs() < 1e-15, "{x}");
        }
    }

    #[test]
    fn impact_coefficients_give_contact_time_and_overlap() {
        let (mu, k) = (0.032, 1.7e10);
        let (a, b) = impact_coefficients(mu, k);
        for u in [1e-3, 0.7, 5.0] {
            let w = fifth_root(u);
            assert!((a / w / contact_time(mu, k, u) - 1.0).abs() < 1e-14);
            assert!((b * u / w / max_overlap(mu, k, u) - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn contact_time_constant_matches_gamma_formula() {
        // Γ(2/5) = 2.218159543757688, Γ(9/10) = 1.068628702119319
        let c = 2.0 * 1.25f64.powf(0.4) * 0.4 * std::f64::consts::PI.sqrt() * 2.218_159_543_757_688
            / 1.068_628_702_119_319;
        assert!((c - CONTACT_TIME_CONST).abs() < 1e-12, "{c}");
    }

    #[test]
    fn hunt_crossley_inverse_gives_restitution() {
        assert!((hunt_crossley_restitution(0.0) - 1.0).abs() < 1e-6);
        for e in [0.95, 0.8, 0.5, 0.2] {
            let a = hunt_crossley_a(e);
            assert!(a > 0.0);
            assert!((hunt_crossley_restitution(a) - e).abs() < 1e-6, "e {e}");
        }
        // the low-damping limit of Hunt–Crossley: a ≈ 3(1−e)/2
        let a = hunt_crossley_a(0.999);
        assert!((a / (1.5 * 0.001) - 1.0).abs() < 0.01, "{a}");
    }

    #[test]
    fn force_is_zero_in_tension_and_matches_power_law() {
        assert_eq!(hertz_force(2.0f64, -1e-6), 0.0);
        let d = 3e-5f64;
        let f = hertz_force(1.5e10f64, d);
        assert!((f - 1.5e10 * d.powf(1.5)).abs() < 1e-12 * f);
    }
}
