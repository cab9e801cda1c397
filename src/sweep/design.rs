//! Sampling designs (`[sample]`): point `i` of `n` in the unit cube, one
//! coordinate per axis, computed from `i` alone (no state, no stored
//! sample), so that any shard or resumed run draws its own slice and the
//! same seed gives the same bytes.
//!
//! - `random`: independent uniform coordinates (a counter-based generator:
//!   splitmix64 of seed, axis and index).
//! - `lhs`: a Latin hypercube: on every axis the n points fall one in each of
//!   the n strata [k/n, (k+1)/n), in a seeded random order (a Feistel
//!   permutation of 0..n, computed per index), uniform within the stratum.
//! - `sobol`: the Sobol sequence with Joe & Kuo's direction numbers (from
//!   the `sobol` crate), point i in Gray-code order (the crate's order);
//!   seed 0 is the plain sequence (point 0 is the origin), another seed a
//!   random digital shift of it.

use std::sync::OnceLock;

use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Design {
    Sobol,
    Lhs,
    Random,
}

impl Design {
    pub fn parse(s: &str) -> Option<Design> {
        match s {
            "sobol" => Some(Design::Sobol),
            "lhs" => Some(Design::Lhs),
            "random" => Some(Design::Random),
            _ => None,
        }
    }
}

/// Most axes a Sobol design may have (the direction numbers bundled).
pub const MAX_SOBOL_AXES: usize = 64;

fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

pub(crate) fn hash(seed: u64, a: u64, b: u64, c: u64) -> u64 {
    mix(mix(mix(mix(seed) ^ a) ^ b) ^ c)
}

/// A uniform number in [0, 1) from 53 bits of `h`.
pub(crate) fn unit_of(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// A seeded permutation of 0..n (n ≥ 1), evaluated at `i`: a 4-round
/// Feistel network on the smallest even number of bits covering n, walked
/// until it lands below n (a bijection of 0..n).
pub fn permute(i: u64, n: u64, seed: u64, axis: u64) -> u64 {
    if n <= 1 {
        return 0;
    }
    let bits = 64 - (n - 1).leading_zeros();
    let half = bits.div_ceil(2).max(1);
    let mask = (1u64 << half) - 1;
    let mut x = i;
    loop {
        let (mut l, mut r) = (x >> half, x & mask);
        for round in 0..4 {
            let f = hash(seed, axis, round, r) & mask;
            (l, r) = (r, l ^ f);
        }
        x = (l << half) | r;
        if x < n {
            return x;
        }
    }
}

fn sobol_directions() -> &'static Vec<Vec<u64>> {
    static DIRS: OnceLock<Vec<Vec<u64>>> = OnceLock::new();
    DIRS.get_or_init(|| {
        sobol::Sobol::<f64>::init_direction_vals::<u32>(
            MAX_SOBOL_AXES,
            53,
            &sobol::params::JoeKuoD6::minimal(),
        )
    })
}

/// Coordinate `axis` of point `i` of a design of `n` points, in [0, 1).
pub fn unit(design: Design, i: u64, n: u64, axis: usize, seed: u64) -> f64 {
    let a = axis as u64;
    match design {
        Design::Random => unit_of(hash(seed, a, 1, i)),
        Design::Lhs => {
            let stratum = permute(i, n, seed, a);
            // Within the stratum; clamped so that rounding never leaves it.
            let u = (stratum as f64 + unit_of(hash(seed, a, 2, i))) / n as f64;
            u.min(((stratum + 1) as f64 / n as f64).next_down())
        }
        Design::Sobol => {
            let dirs = &sobol_directions()[axis];
            let gray = i ^ (i >> 1);
            let mut x = 0u64;
            for (j, d) in dirs.iter().enumerate().take(64) {
                if gray >> j & 1 == 1 {
                    x ^= d;
                }
            }
            if seed != 0 {
                // A digital shift of the 53 bits the sequence uses.
                x ^= hash(seed, a, 3, 0) & !((1u64 << 11) - 1);
            }
            x as f64 / 18_446_744_073_709_551_616_f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_latin_hypercube_hits_every_stratum_of_every_axis_once() {
        for n in [1u64, 2, 7, 100, 1000, 4097] {
            for axis in 0..3 {
                let mut hit = vec![false; n as usize];
                for i in 0..n {
                    let u = unit(Design::Lhs, i, n, axis, 42);
                    assert!((0.0..1.0).contains(&u));
                    let k = (u * n as f64).floor() as usize;
                    assert!(!hit[k], "n {n}: stratum {k} twice");
                    hit[k] = true;
                }
            }
        }
        // Another seed, another order; the same seed, the same points.
        let a: Vec<f64> = (0..50).map(|i| unit(Design::Lhs, i, 50, 0, 1)).collect();
        let b: Vec<f64> = (0..50).map(|i| unit(Design::Lhs, i, 50, 0, 2)).collect();
        assert_ne!(a, b);
        assert_eq!(
            a,
            (0..50)
                .map(|i| unit(Design::Lhs, i, 50, 0, 1))
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn sobol_points_from_their_index_are_the_crates_sequence() {
        let seq = sobol::Sobol::<f64>::new(5, &sobol::params::JoeKuoD6::minimal());
        for (i, p) in seq.take(5000).enumerate() {
            for (k, x) in p.iter().enumerate() {
                assert_eq!(
                    unit(Design::Sobol, i as u64, 5000, k, 0),
                    *x,
                    "point {i} axis {k}"
                );
            }
        }
        // A shifted sequence is still a net: 2^m points, one in each
        // dyadic interval of length 2^-m on every axis.
        let m = 1u64 << 10;
        for k in 0..4 {
            let mut hit = vec![false; m as usize];
            for i in 0..m {
                let u = unit(Design::Sobol, i, m, k, 7);
                hit[(u * m as f64) as usize] = true;
            }
            assert!(hit.iter().all(|&h| h), "axis {k}");
        }
    }

    #[test]
    fn random_points_are_uniform_and_reproducible() {
        let n = 100_000;
        let mean = (0..n)
            .map(|i| unit(Design::Random, i, n, 0, 9))
            .sum::<f64>()
            / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
        assert_eq!(
            unit(Design::Random, 17, n, 2, 9),
            unit(Design::Random, 17, n, 2, 9)
        );
        assert_ne!(
            unit(Design::Random, 17, n, 2, 9),
            unit(Design::Random, 17, n, 2, 10)
        );
    }
}
