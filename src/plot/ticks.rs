//! Tick labels as a paper writes them: an axis of lengths from 0 to 5e-6 m
//! reads 0, 1, …, 5 under "gap (µm)" (an SI prefix on its unit, as
//! matplotlib's `EngFormatter`), a unitless one ×10⁻⁶ in its label, a
//! narrow range 0.9936, 0.9938, … with the digits that tell its ticks
//! apart (not "0.994" six times), and one whose ticks differ only past the
//! fifth digit as an offset: "ratio − 0.99".

use plotters::coord::ranged1d::Ranged;
use plotters::coord::types::RangedCoordf64;

/// The SI prefixes an axis may take, by power of ten.
const PREFIXES: [(i32, &str); 10] = [
    (-15, "f"),
    (-12, "p"),
    (-9, "n"),
    (-6, "µ"),
    (-3, "m"),
    (0, ""),
    (3, "k"),
    (6, "M"),
    (9, "G"),
    (12, "T"),
];

/// Units an SI prefix can go in front of (kg/m³ or 1/s read badly with
/// one; kg becomes g first).
fn prefixable(unit: &str) -> bool {
    matches!(
        unit,
        "m" | "s" | "N" | "Pa" | "m/s" | "m/s²" | "N·s" | "J" | "Hz" | "N·s/m" | "g"
    )
}

/// `10⁻⁶`: a power of ten in superscript digits.
pub fn power_of_ten(e: i32) -> String {
    let sup = |c: char| match c {
        '-' => '⁻',
        d => ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'][d as usize - '0' as usize],
    };
    format!("10{}", e.to_string().chars().map(sup).collect::<String>())
}

/// A value with its unit, SI-prefixed as an axis would print it: `si(1.2e-4,
/// "m")` is "120 µm".
pub fn si(v: f64, unit: &str) -> String {
    let (unit, to_unit) = grams(Some(unit));
    let unit = unit.unwrap_or_default();
    let x = (v * to_unit).abs();
    let (p, u) = prefixed(exponent(x), unit)
        .filter(|_| x > 0.0)
        .unwrap_or((0, unit.to_string()));
    let s = format!("{:.3}", v * to_unit * 10f64.powi(-p));
    format!("{} {u}", s.trim_end_matches('0').trim_end_matches('.'))
}

/// The power of ten of `top` (> 0): 2 for 150.
fn exponent(top: f64) -> i32 {
    (top.log10() + 1e-9).floor() as i32
}

/// For a largest value 10^`e` in `unit`, the SI prefix's power (a multiple
/// of 3) and the prefixed unit ("µm"; grams of 10³ and up read kg), if the
/// unit takes a prefix.
fn prefixed(e: i32, unit: &str) -> Option<(i32, String)> {
    if !prefixable(unit) {
        return None;
    }
    let p = (e.div_euclid(3) * 3).clamp(-15, 12);
    let prefix = PREFIXES.iter().find(|x| x.0 == p).map_or("", |x| x.1);
    Some(if p == 3 && unit == "g" {
        (p, "kg".to_string())
    } else {
        (p, format!("{prefix}{unit}"))
    })
}

/// How one axis prints its ticks, and the label that says so.
#[derive(Clone, Debug)]
pub struct Ticks {
    /// Where the ticks go (the axis's own coordinates).
    pub at: Vec<f64>,
    /// The axis label: the quantity and its (prefixed) unit, any ×10ᵏ
    /// factor and offset.
    pub label: String,
    /// A tick at v reads (v − offset) · scale …
    scale: f64,
    offset: f64,
    /// … with this many decimals (None: each tick its own shortest form).
    decimals: Option<usize>,
    /// On a log axis (coordinates log10 of the value) over more than three
    /// decades: each tick reads 10ᵏ.
    powers: bool,
    log: bool,
}

impl Ticks {
    /// Ticks at `at` (ascending) on a linear axis of quantity `name` in
    /// `unit`.
    pub fn linear(name: &str, unit: Option<&str>, at: Vec<f64>) -> Ticks {
        let (unit, to_unit) = grams(unit);
        let top = at.iter().fold(0.0f64, |m, v| m.max((v * to_unit).abs()));
        let step = at
            .windows(2)
            .map(|w| (w[1] - w[0]) * to_unit)
            .filter(|d| *d > 0.0)
            .fold(f64::INFINITY, f64::min);
        if !(step.is_finite() && top / step > 1e5) {
            return Ticks::scaled(name.to_string(), unit, at, to_unit, 0.0, top, step);
        }
        // Ticks alike in their first five digits: a round offset off them.
        let k = step.log10().ceil() as i32 + 1;
        let round = 10f64.powi(k);
        let offset = (at[0] * to_unit / round).floor() * round;
        let name = format!(
            "{name} − {}{}",
            number(offset),
            unit.map_or(String::new(), |u| format!(" {u}"))
        );
        let top = at
            .iter()
            .fold(0.0f64, |m, v| m.max((v * to_unit - offset).abs()));
        Ticks::scaled(name, unit, at, to_unit, offset, top, step)
    }

    /// Ticks reading (v·`to_unit` − `offset`), scaled by an SI prefix of
    /// `unit` or a power of ten to the largest of them, `top`.
    fn scaled(
        name: String,
        unit: Option<&str>,
        at: Vec<f64>,
        to_unit: f64,
        offset: f64,
        top: f64,
        step: f64,
    ) -> Ticks {
        let e = if top > 0.0 { exponent(top) } else { 0 };
        let si = unit.filter(|_| top > 0.0).and_then(|u| prefixed(e, u));
        let (label, p) = match (si, unit) {
            (Some((p, u)), _) => (format!("{name} ({u})"), p),
            _ if top > 0.0 && !(-2..4).contains(&e) => {
                let p = e.div_euclid(3) * 3;
                let u = unit.map_or(String::new(), |u| format!(" {u}"));
                (format!("{name} (×{}{u})", power_of_ten(p)), p)
            }
            (None, Some(u)) => (format!("{name} ({u})"), 0),
            (None, None) => (name, 0),
        };
        let s = 10f64.powi(-p);
        Ticks::fixed(at, label, to_unit * s, offset * s, step * s)
    }

    /// `n` ticks plotters would choose over `lo..hi`, as [`Ticks::linear`].
    pub fn over(name: &str, unit: Option<&str>, lo: f64, hi: f64, n: usize) -> Ticks {
        Ticks::linear(name, unit, RangedCoordf64::from(lo..hi).key_points(n))
    }

    /// Ticks at `at` (log10 of the values) on a log axis spanning
    /// `decades`: over more than three, each reads 10ᵏ under the plain
    /// unit; else as on a linear axis of the values.
    pub fn log(name: &str, unit: Option<&str>, at: Vec<f64>, decades: f64) -> Ticks {
        let values: Vec<f64> = at.iter().map(|c| 10f64.powf(*c)).collect();
        let mut t = if decades > 3.0 {
            let label = match unit {
                Some(u) => format!("{name} ({u})"),
                None => name.to_string(),
            };
            Ticks {
                at: vec![],
                label,
                scale: 1.0,
                offset: 0.0,
                decimals: None,
                powers: true,
                log: true,
            }
        } else {
            let mut t = Ticks::linear(name, unit, values);
            t.decimals = None;
            t.log = true;
            t
        };
        t.at = at;
        t.label += ", log scale";
        t
    }

    fn fixed(at: Vec<f64>, label: String, scale: f64, offset: f64, step: f64) -> Ticks {
        // Enough decimals that every tick prints as itself (to a millionth
        // of the spacing), at most 10.
        let decimals = (0..=10)
            .find(|&d| {
                let q = 10f64.powi(d as i32);
                at.iter().all(|&v| {
                    let x = v * scale - offset;
                    ((x * q).round() / q - x).abs() <= 1e-6 * step.min(x.abs().max(step))
                })
            })
            .unwrap_or(10);
        Ticks {
            at,
            label,
            scale,
            offset,
            decimals: Some(decimals),
            powers: false,
            log: false,
        }
    }

    /// The label of the tick at coordinate `c`.
    pub fn format(&self, c: f64) -> String {
        if self.powers {
            return power_of_ten(c.round() as i32);
        }
        let v = if self.log { 10f64.powf(c) } else { c };
        let x = v * self.scale - self.offset;
        let s = match self.decimals {
            Some(d) => format!("{x:.d$}"),
            None => {
                // A log axis's 1, 2, 5 × 10ᵏ: the shortest form.
                let s = format!("{:.6}", x);
                s.trim_end_matches('0').trim_end_matches('.').to_string()
            }
        };
        // No "-0.0" from round-off about zero.
        if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
            s[1..].to_string()
        } else {
            s
        }
    }
}

/// A unit as an axis prints it and the factor from the column's value:
/// kilograms as grams (so that a prefix can go in front).
fn grams(unit: Option<&str>) -> (Option<&str>, f64) {
    match unit {
        Some("kg") => (Some("g"), 1e3),
        u => (u, 1.0),
    }
}

/// A number in a label (a discrete colour's value, an offset): 3
/// significant digits, e.g. 0.99, 1.25e-7.
pub fn number(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if !(1e-3..1e4).contains(&v.abs()) {
        format!("{v:.2e}")
    } else {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(t: &Ticks) -> Vec<String> {
        t.at.iter().map(|&c| t.format(c)).collect()
    }

    #[test]
    fn lengths_and_times_take_an_si_prefix() {
        let t = Ticks::linear("gap", Some("m"), vec![0.0, 1e-6, 2e-6, 3e-6, 4e-6, 5e-6]);
        assert_eq!(t.label, "gap (µm)");
        assert_eq!(labels(&t), ["0", "1", "2", "3", "4", "5"]);
        let t = Ticks::linear("t", Some("s"), vec![0.0, 0.0025, 0.005, 0.0075]);
        assert_eq!(t.label, "t (ms)");
        assert_eq!(labels(&t), ["0.0", "2.5", "5.0", "7.5"]);
        let t = Ticks::linear("mass", Some("kg"), vec![0.002, 0.004, 0.006]);
        assert_eq!(t.label, "mass (g)");
        assert_eq!(labels(&t), ["2", "4", "6"]);
        let t = Ticks::linear("young_modulus", Some("Pa"), vec![1e11, 2e11]);
        assert_eq!(t.label, "young_modulus (GPa)");
        assert_eq!(labels(&t), ["100", "200"]);
        assert_eq!(si(1.2e-4, "m"), "120 µm");
        assert_eq!(si(0.0123, "s"), "12.3 ms");
    }

    #[test]
    fn unitless_small_numbers_take_a_power_of_ten_and_narrow_ranges_their_digits() {
        let t = Ticks::linear("energy_error", None, vec![0.0, 2e-7, 4e-7]);
        assert_eq!(t.label, "energy_error (×10⁻⁹)");
        assert_eq!(labels(&t), ["0", "200", "400"]);
        let at: Vec<f64> = (0..6).map(|k| 0.9936 + 2e-4 * k as f64).collect();
        let t = Ticks::linear("ratio", None, at);
        assert_eq!(t.label, "ratio");
        assert_eq!(
            labels(&t),
            ["0.9936", "0.9938", "0.9940", "0.9942", "0.9944", "0.9946"]
        );
        let at: Vec<f64> = (0..3).map(|k| 0.99 + 1e-8 * k as f64).collect();
        let t = Ticks::linear("ratio", None, at);
        assert_eq!(t.label, "ratio − 0.99 (×10⁻⁹)");
        assert_eq!(labels(&t), ["0", "10", "20"]);
    }

    #[test]
    fn log_axes_read_powers_of_ten_or_prefixed_values() {
        let at: Vec<f64> = (-12..=-4).step_by(2).map(|k| k as f64).collect();
        let t = Ticks::log("gap", Some("m"), at, 8.0);
        assert_eq!(t.label, "gap (m), log scale");
        assert_eq!(labels(&t), ["10⁻¹²", "10⁻¹⁰", "10⁻⁸", "10⁻⁶", "10⁻⁴"]);
        let at: Vec<f64> = [1e-3f64, 2e-3, 5e-3, 1e-2]
            .iter()
            .map(|v| v.log10())
            .collect();
        let t = Ticks::log("radius", Some("m"), at, 1.0);
        assert_eq!(t.label, "radius (mm), log scale");
        assert_eq!(labels(&t), ["1", "2", "5", "10"]);
    }
}
