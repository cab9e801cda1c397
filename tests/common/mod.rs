//! Helpers shared by the integration tests.
#![allow(dead_code)]

/// Mass of the default steel ball (R = 12.5 mm, ρ = 7850 kg/m³), kg.
pub const STEEL_MASS: f64 = 7850.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.0125 * 0.0125 * 0.0125;

/// A deterministic uniform generator on [0, 1) (xorshift64): fixed test batches
/// without a dependency on a random-number crate.
pub fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}
