//! A granular chain's outcome as columns (docs/SPEC.md §9): per probe bead
//! its leading pulse, then the pulse speed and width, the walls, the
//! energy partition, fragments and diagnostics. A row is never 10^4
//! columns wide: final velocities for every bead up to
//! [`crate::scene::MAX_BALLS`] beads, for the probe beads only above.

use super::row::{ColType, Field};
use crate::engine::granular::{Beads, ChainOutcome, WallOutcome};
use crate::scene::MAX_BALLS;

/// Which bead columns a chain table has: each probe's leading pulse, and
/// the final velocities of `velocities` (every bead up to
/// [`MAX_BALLS`] beads, the probes above).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Columns {
    pub probes: Vec<usize>,
    pub velocities: Vec<usize>,
    /// Whether the table has `energy_dissipated` (after `energy_left`):
    /// a damped chain's (issue #45).
    pub damped: bool,
    /// Whether it has `shock_speed` and `piston_work` (after
    /// `pulse_width`): a chain with a piston's.
    pub piston: bool,
    /// Whether each probe has `amplitude_<b>` (after its `peak_f_<b>`): a
    /// driven chain's.
    pub drive: bool,
}

/// The columns after the per-bead ones, in order.
const TAIL: [&str; 17] = [
    "pulse_speed",
    "pulse_width",
    "wall_left_peak_force",
    "wall_left_impulse",
    "wall_right_peak_force",
    "wall_right_impulse",
    "energy_reflected",
    "energy_transmitted",
    "energy_left",
    "fragments",
    "energy_error",
    "momentum_error",
    "max_overlap_ratio",
    "t_end",
    "steps",
    "dt",
    "error_estimate",
];

impl Columns {
    /// The columns of one chain's row (`cradle run`).
    pub fn of(b: &Beads) -> Columns {
        let drive = b.pulse.as_ref().is_some_and(|p| p.is_drive());
        Self::for_chains(b.probes.clone(), b.n, [b.damped(), b.piston > 0.0, drive])
    }

    /// The columns of a table of chains of at most `most_beads` beads with
    /// these probe beads (a sweep's: the base scene's probes); `[damped,
    /// piston, drive]`: with `energy_dissipated`, with `shock_speed` and
    /// `piston_work`, with `amplitude_<b>`.
    pub fn for_chains(
        probes: Vec<usize>,
        most_beads: usize,
        [damped, piston, drive]: [bool; 3],
    ) -> Columns {
        let velocities = if most_beads <= MAX_BALLS {
            (0..most_beads).collect()
        } else {
            probes.clone()
        };
        Columns {
            probes,
            velocities,
            damped,
            piston,
            drive,
        }
    }

    /// Column names (after a sweep's `id` and axis columns).
    pub fn header(&self) -> Vec<String> {
        let mut h = vec!["status".to_string()];
        for p in &self.probes {
            for c in ["arrival", "peak_v", "peak_f"] {
                h.push(format!("{c}_{p}"));
            }
            if self.drive {
                h.push(format!("amplitude_{p}"));
            }
        }
        h.extend(self.velocities.iter().map(|i| format!("v_{i}")));
        h.extend(self.tail().map(|c| c.to_string()));
        h
    }

    /// The columns after the per-bead ones: [`TAIL`], with
    /// `energy_dissipated` after `energy_left` when damped, `shock_speed`
    /// and `piston_work` after `pulse_width` with a piston.
    fn tail(&self) -> impl Iterator<Item = &'static str> + '_ {
        TAIL.iter().flat_map(move |&c| {
            let extra: &[&'static str] = match c {
                "energy_left" if self.damped => &["energy_dissipated"],
                "pulse_width" if self.piston => &["shock_speed", "piston_work"],
                _ => &[],
            };
            std::iter::once(c).chain(extra.iter().copied())
        })
    }

    /// Number of columns ([`Columns::header`]'s length).
    pub fn width(&self) -> usize {
        1 + (3 + self.drive as usize) * self.probes.len()
            + self.velocities.len()
            + TAIL.len()
            + self.damped as usize
            + 2 * self.piston as usize
    }

    /// The fields of a row as the CSV writes them, in
    /// [`Columns::header`]'s order.
    pub fn texts(&self, o: &ChainOutcome) -> Vec<String> {
        let (mut f, mut s) = (Vec::with_capacity(self.width()), String::new());
        self.emit(o, &mut |x| {
            f.push(super::row::field_text(x, &mut s).to_string())
        });
        f
    }

    /// Column types, parallel to [`Columns::header`].
    pub fn types(&self) -> Vec<ColType> {
        use ColType::*;
        let mut t = vec![Status];
        t.extend(std::iter::repeat_n(
            Num,
            (3 + self.drive as usize) * self.probes.len() + self.velocities.len(),
        ));
        t.extend(self.tail().map(|c| match c {
            "fragments" | "steps" => Int,
            _ => Num,
        }));
        t
    }

    /// The fields of a row in [`Columns::header`]'s order (NaN: missing).
    /// A combination of sweep values that made no valid chain (status
    /// `invalid`) has every other field missing; a `non_finite` run's state
    /// is garbage, so only its `t_end`, `steps` and `dt` are written. A
    /// velocity column of a bead the chain does not have (a `balls` axis)
    /// is missing too.
    pub fn emit(&self, o: &ChainOutcome, out: &mut dyn FnMut(Field)) {
        use crate::engine::Status;
        out(Field::Text(o.status.name()));
        if o.status == Status::Invalid {
            (1..self.width()).for_each(|_| out(Field::Null));
            return;
        }
        let garbage = o.status == Status::NonFinite;
        let num = |x: f64, out: &mut dyn FnMut(Field)| {
            out(if garbage { Field::Null } else { Field::Num(x) })
        };
        for (k, p) in o.probes.iter().enumerate() {
            num(p.arrival, out);
            num(p.peak_velocity, out);
            num(p.peak_force, out);
            if self.drive {
                num(o.amplitudes.get(k).copied().unwrap_or(f64::NAN), out);
            }
        }
        for &i in &self.velocities {
            match o.v.get(i) {
                Some(&v) => num(v, out),
                None => out(Field::Null),
            }
        }
        let wall = |w: &Option<WallOutcome>| {
            w.as_ref()
                .map_or((f64::NAN, f64::NAN), |w| (w.peak_force, w.impulse))
        };
        let (lp, li) = wall(&o.left_wall);
        let (rp, ri) = wall(&o.right_wall);
        num(o.pulse_speed, out);
        num(o.pulse_width, out);
        if self.piston {
            num(o.shock_speed, out);
            num(o.piston_work, out);
        }
        for x in [
            lp,
            li,
            rp,
            ri,
            o.energy_reflected,
            o.energy_transmitted,
            o.energy_left,
        ] {
            num(x, out);
        }
        if self.damped {
            num(o.energy_dissipated, out);
        }
        out(if garbage {
            Field::Null
        } else {
            Field::Int(o.fragments as u64)
        });
        for x in [o.energy_error, o.momentum_error, o.max_overlap_ratio] {
            num(x, out);
        }
        out(Field::Num(o.t_end));
        out(Field::Int(o.steps));
        out(Field::Num(o.dt));
        num(o.error_estimate, out);
    }
}

/// Column names of a chain's row (`cradle run --format csv`).
pub fn header(b: &Beads) -> Vec<String> {
    Columns::of(b).header()
}

/// The row's fields as text, in [`header`]'s order (NaN: empty).
pub fn fields(b: &Beads, o: &ChainOutcome) -> Vec<String> {
    Columns::of(b).texts(o)
}

/// A human-readable table of one chain run (`cradle run`).
pub fn table(name: &str, b: &Beads, o: &ChainOutcome) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "scene   {name}  (granular chain of {} beads)", b.n);
    let _ = writeln!(s, "status  {}", o.status);
    if !o.probes.is_empty() {
        let _ = writeln!(
            s,
            "\n probe   arrival (s)    peak v (m/s)   peak force (N)   v_final (m/s)"
        );
        for p in &o.probes {
            let _ = writeln!(
                s,
                " {:>5}   {:>11.6e}   {:>12.6e}   {:>14.6e}   {:>13.6e}",
                p.bead, p.arrival, p.peak_velocity, p.peak_force, p.v_final
            );
        }
        let _ = writeln!(s);
        let _ = writeln!(s, "pulse_speed        {:.6} m/s", o.pulse_speed);
        let _ = writeln!(s, "pulse_width        {:.4} beads (FWHM)", o.pulse_width);
    }
    if o.left_wall.is_some() || o.right_wall.is_some() {
        let _ = writeln!(
            s,
            "walls              (impulse: ∫(F − F0) dt, the push a wall takes beyond its preload; positive)"
        );
    }
    for (side, w) in [("left", &o.left_wall), ("right", &o.right_wall)] {
        if let Some(w) = w {
            let _ = writeln!(
                s,
                "wall_{side:<5}         peak {:.6e} N, impulse {:.6e} N·s{}",
                w.peak_force,
                w.impulse,
                if w.in_contact {
                    " (partial: its bead still touches it at t_end; set [stop] duration for the whole rebound)"
                } else {
                    ""
                }
            );
        }
    }
    if !o.probes.is_empty() {
        let _ = writeln!(
            s,
            "energy             reflected {:.6}, transmitted {:.6}, left {:.6}  (fractions of the energy put in: before the first probe, after the last, between)",
            o.energy_reflected, o.energy_transmitted, o.energy_left
        );
    }
    let _ = writeln!(s, "fragments          {}", o.fragments);
    if b.piston > 0.0 {
        let _ = writeln!(
            s,
            "piston             {} m/s: shock_speed {:.6} m/s (probes' velocity reaching half of it), work {:.6e} J",
            b.piston, o.shock_speed, o.piston_work
        );
    }
    if b.damped() {
        let _ = writeln!(
            s,
            "energy_dissipated  {:.6e} J  (by the dashpots and the air drag)",
            o.energy_dissipated
        );
    }
    let _ = writeln!(
        s,
        "energy_error       {:.3e}  (relative{})",
        o.energy_error,
        if b.damped() {
            "; of the energy plus what the damping took"
        } else {
            ""
        }
    );
    if b.left_wall || b.right_wall {
        // A wall takes momentum: there is no conservation to check.
        let _ = writeln!(s, "momentum_error     n/a (walls take momentum)");
    } else if b.air_drag > 0.0 {
        let _ = writeln!(s, "momentum_error     n/a (the air drag takes momentum)");
    } else {
        let _ = writeln!(s, "momentum_error     {:.3e}  (relative)", o.momentum_error);
    }
    let _ = writeln!(
        s,
        "max_overlap_ratio  {:.3e}  (largest overlap / the smaller radius of its contact)",
        o.max_overlap_ratio
    );
    let _ = writeln!(
        s,
        "t_end              {:.6e} s, {} steps (dt = {:.4e} s)",
        o.t_end, o.steps, o.dt
    );
    let against = o.tolerance.map_or("a given step".to_string(), |tol| {
        format!("tolerance {tol:e}")
    });
    let _ = writeln!(
        s,
        "error_estimate     {:.3e}  (of the velocity scale; {against})",
        o.error_estimate
    );
    s
}
