//! One outcome row, the same for `cradle run --format csv` and every sweep row
//! (SPEC §4): `id`, one column per axis, `status`, `v_0`..`v_{N−1}`, on a
//! pendulum the final displacements `x_0`..`x_{N−1}` (m, arc length),
//! `ejected`, `energy_error`, `momentum_error` (empty on a pendulum, where
//! gravity changes momentum), `max_overlap_m`, `steps`, then `contacts`
//! (contact onsets), `energy_left` (final / initial energy), `energy_last`
//! (the last ball's kinetic energy / initial energy), `t_contact`,
//! `t_release`, `dt` (s), `error_estimate` (relative to v_in, with
//! `--error-estimate`; empty otherwise).

use crate::engine::{Outcome, Status};

/// Which per-ball columns a table has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    /// The largest number of balls.
    pub width: usize,
    /// Pendulum scenes: final displacements `x_i` too.
    pub pendulum: bool,
}

/// Column names for `axes` and a table of `shape`.
pub fn header(axes: &[String], shape: Shape) -> Vec<String> {
    let width = shape.width;
    let mut h = vec!["id".to_string()];
    h.extend(axes.iter().cloned());
    h.push("status".into());
    h.extend((0..width).map(|i| format!("v_{i}")));
    if shape.pendulum {
        h.extend((0..width).map(|i| format!("x_{i}")));
    }
    for c in [
        "ejected",
        "energy_error",
        "momentum_error",
        "max_overlap_m",
        "steps",
        "contacts",
        "energy_left",
        "energy_last",
        "t_contact",
        "t_release",
        "dt",
        "error_estimate",
    ] {
        h.push(c.into());
    }
    h
}

/// A float as the CSV writes it: shortest round-trip text; NaN → empty.
pub fn num(x: f64) -> String {
    if x.is_nan() {
        String::new()
    } else if x == 0.0 || (1e-3..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The fields of one row; missing balls (N below `width`) are empty. A
/// `non_finite` run's state is garbage (±inf, 1e130): its velocities,
/// displacements, `ejected` and energy/momentum/overlap columns are empty
/// rather than numbers that look like results.
pub fn fields(id: u64, axis_values: &[String], o: &Outcome, shape: Shape) -> Vec<String> {
    let width = shape.width;
    let garbage = o.status == Status::NonFinite;
    let state = |x: f64| if garbage { String::new() } else { num(x) };
    let mut r = Vec::with_capacity(14 + axis_values.len() + 2 * width);
    r.push(id.to_string());
    r.extend(axis_values.iter().cloned());
    r.push(o.status.name().to_string());
    r.extend((0..width).map(|i| o.v.get(i).map_or(String::new(), |&v| state(v))));
    if shape.pendulum {
        r.extend((0..width).map(|i| o.x.get(i).map_or(String::new(), |&x| state(x))));
    }
    r.push(if o.status == Status::Invalid || garbage {
        String::new()
    } else {
        o.ejected.to_string()
    });
    for x in [o.energy_error, o.momentum_error, o.max_overlap_m] {
        r.push(state(x));
    }
    r.push(o.steps.to_string());
    r.push(o.contacts.to_string());
    r.push(state(o.energy_left));
    r.push(state(o.energy_last));
    for x in [o.t_contact, o.t_release, o.dt, o.error_estimate] {
        r.push(num(x));
    }
    r
}

/// A human-readable table of one outcome (`cradle run`).
pub fn table(name: &str, v_in: f64, v0: &[f64], o: &Outcome, pendulum: bool) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "scene   {name}");
    let _ = writeln!(s, "status  {}", o.status);
    if pendulum {
        let _ = writeln!(
            s,
            "\n ball   v_initial (m/s)   v_final (m/s)   v_final / v_in   x_final (m)"
        );
    } else {
        let _ = writeln!(
            s,
            "\n ball   v_initial (m/s)   v_final (m/s)   v_final / v_in"
        );
    }
    for (i, (a, b)) in v0.iter().zip(&o.v).enumerate() {
        let _ = write!(s, " {i:>4}   {a:>15.6}   {b:>13.8}   {:>14.8}", b / v_in);
        if pendulum {
            let _ = write!(s, "   {:>11.4e}", o.x[i]);
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "ejected          {}", o.ejected);
    let _ = writeln!(s, "energy_error     {:.3e}  (relative)", o.energy_error);
    let _ = writeln!(s, "momentum_error   {:.3e}  (relative)", o.momentum_error);
    let _ = writeln!(
        s,
        "energy_left      {:.9}  (final / initial)",
        o.energy_left
    );
    let _ = writeln!(s, "max_overlap      {:.6e} m", o.max_overlap_m);
    let _ = writeln!(s, "contacts         {}", o.contacts);
    let _ = writeln!(
        s,
        "contact          {:.6e} s .. {:.6e} s",
        o.t_contact, o.t_release
    );
    let _ = writeln!(s, "steps            {}  (dt = {:.4e} s)", o.steps, o.dt);
    s
}

#[cfg(test)]
mod tests {
    use super::num;

    #[test]
    fn numbers_round_trip() {
        for x in [
            0.0,
            1.0,
            -0.07109,
            1e-14,
            2.6055e-5,
            123456789.0,
            -1.0 / 3.0,
        ] {
            assert_eq!(num(x).parse::<f64>().unwrap(), x);
        }
        assert_eq!(num(f64::NAN), "");
    }

    #[test]
    fn a_non_finite_row_shows_no_garbage_state() {
        use crate::engine::{Outcome, Status};
        let o = Outcome {
            status: Status::NonFinite,
            v: vec![f64::INFINITY, -1e130, 0.5],
            ejected: 2,
            energy_error: f64::INFINITY,
            momentum_error: 1e130,
            max_overlap_m: f64::NEG_INFINITY,
            steps: 77,
            energy_left: 1e130,
            energy_last: f64::INFINITY,
            contacts: 3,
            x: vec![1e130; 3],
            t_end: 1.0,
            t_contact: 1e-4,
            t_release: 2e-4,
            dt: 1e-7,
            error_estimate: f64::NAN,
        };
        let shape = super::Shape {
            width: 3,
            pendulum: true,
        };
        let f = super::fields(4, &["0.5".into()], &o, shape);
        let h = super::header(&["mass".into()], shape);
        let col = |c: &str| f[h.iter().position(|x| x == c).unwrap()].as_str();
        assert_eq!((col("id"), col("status")), ("4", "non_finite"));
        for c in [
            "v_0",
            "v_1",
            "v_2",
            "x_0",
            "ejected",
            "energy_error",
            "momentum_error",
            "max_overlap_m",
            "energy_left",
            "energy_last",
        ] {
            assert_eq!(col(c), "", "{c}");
        }
        assert_eq!((col("steps"), col("dt")), ("77", "1e-7"));
        assert!(f.iter().all(|x| !x.contains("inf") && !x.contains("e130")));
    }
}
