//! A granular chain's outcome as columns (docs/SPEC.md §9): per probe bead
//! its leading pulse, then the pulse speed and width, the walls, the
//! energy partition, fragments and diagnostics. A row is never 10^4
//! columns wide: final velocities for every bead up to
//! [`crate::scene::MAX_BALLS`] beads, for the probe beads only above.

use crate::engine::granular::{Beads, ChainOutcome};
use crate::scene::MAX_BALLS;

/// The beads whose final velocity is a column.
pub fn velocity_beads(b: &Beads) -> Vec<usize> {
    if b.n <= MAX_BALLS {
        (0..b.n).collect()
    } else {
        b.probes.clone()
    }
}

/// Column names of a chain's row.
pub fn header(b: &Beads) -> Vec<String> {
    let mut h = vec!["status".to_string()];
    for p in &b.probes {
        for c in ["arrival", "peak_v", "peak_f"] {
            h.push(format!("{c}_{p}"));
        }
    }
    h.extend(velocity_beads(b).iter().map(|i| format!("v_{i}")));
    for c in [
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
    ] {
        h.push(c.to_string());
    }
    h
}

/// The row's fields, in [`header`]'s order (NaN: empty).
pub fn fields(b: &Beads, o: &ChainOutcome) -> Vec<String> {
    let mut s = String::new();
    let mut num = |x: f64| {
        super::row::num_into(x, &mut s);
        s.clone()
    };
    let mut f = vec![o.status.name().to_string()];
    for p in &o.probes {
        f.push(num(p.arrival));
        f.push(num(p.peak_velocity));
        f.push(num(p.peak_force));
    }
    for i in velocity_beads(b) {
        f.push(num(o.v[i]));
    }
    let wall = |w: &Option<crate::engine::granular::WallOutcome>| {
        w.as_ref()
            .map_or((f64::NAN, f64::NAN), |w| (w.peak_force, w.impulse))
    };
    let (lp, li) = wall(&o.left_wall);
    let (rp, ri) = wall(&o.right_wall);
    for x in [
        o.pulse_speed,
        o.pulse_width,
        lp,
        li,
        rp,
        ri,
        o.energy_reflected,
        o.energy_transmitted,
        o.energy_left,
    ] {
        f.push(num(x));
    }
    f.push(o.fragments.to_string());
    for x in [
        o.energy_error,
        o.momentum_error,
        o.max_overlap_ratio,
        o.t_end,
    ] {
        f.push(num(x));
    }
    f.push(o.steps.to_string());
    f.push(num(o.dt));
    f
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
    for (side, w) in [("left", &o.left_wall), ("right", &o.right_wall)] {
        if let Some(w) = w {
            let _ = writeln!(
                s,
                "wall_{side:<5}         peak {:.6e} N, impulse {:.6e} N·s",
                w.peak_force, w.impulse
            );
        }
    }
    if !o.probes.is_empty() {
        let _ = writeln!(
            s,
            "energy             reflected {:.6}, transmitted {:.6}, left {:.6}",
            o.energy_reflected, o.energy_transmitted, o.energy_left
        );
    }
    let _ = writeln!(s, "fragments          {}", o.fragments);
    let _ = writeln!(s, "energy_error       {:.3e}  (relative)", o.energy_error);
    let _ = writeln!(s, "momentum_error     {:.3e}  (relative)", o.momentum_error);
    let _ = writeln!(s, "max_overlap_ratio  {:.3e}", o.max_overlap_ratio);
    let _ = writeln!(
        s,
        "t_end              {:.6e} s, {} steps (dt = {:.4e} s)",
        o.t_end, o.steps, o.dt
    );
    s
}
