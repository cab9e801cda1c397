//! The contact law — the one place on the Rust side that says how two balls
//! push on each other. Its WGSL twin is `hertz_force` in `shaders/integrate.wgsl`.
//!
//! Hertz (SPEC §2): overlap δ = x_i − x_{i+1} − g_i; force F = k·δ^{3/2} for δ > 0,
//! zero otherwise (no tension), with k = (4/3)·E*·√R*.

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
/// speed `v` (m/s) (SPEC §6).
pub fn contact_time(mu: f64, k: f64, v: f64) -> f64 {
    CONTACT_TIME_CONST * (mu * mu / (k * k * v)).powf(0.2)
}

/// Largest overlap of a two-body Hertz impact: (5μv²/(4k))^{2/5} (m).
pub fn max_overlap(mu: f64, k: f64, v: f64) -> f64 {
    (5.0 * mu * v * v / (4.0 * k)).powf(0.4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_time_constant_matches_gamma_formula() {
        // Γ(2/5) = 2.218159543757688, Γ(9/10) = 1.068628702119319
        let c = 2.0 * 1.25f64.powf(0.4) * 0.4 * std::f64::consts::PI.sqrt() * 2.218_159_543_757_688
            / 1.068_628_702_119_319;
        assert!((c - CONTACT_TIME_CONST).abs() < 1e-12, "{c}");
    }

    #[test]
    fn force_is_zero_in_tension_and_matches_power_law() {
        assert_eq!(hertz_force(2.0f64, -1e-6), 0.0);
        let d = 3e-5f64;
        let f = hertz_force(1.5e10f64, d);
        assert!((f - 1.5e10 * d.powf(1.5)).abs() < 1e-12 * f);
    }
}
