//! The physical unit of a table's column, from its name (docs/SPEC.md §4
//! keys, the cradle's and the chain's outcome columns, trace columns): for
//! plot labels and the explorer's axes.

/// The unit of column `col`, if it has one (counts, ratios and relative
/// errors have none).
pub fn unit(col: &str) -> Option<&'static str> {
    let base = col.split('[').next().unwrap_or(col);
    let base = base.split('.').next_back().unwrap_or(base);
    Some(match base {
        "gap" | "radius" | "length" | "height" | "max_overlap_m" => "m",
        "mass" => "kg",
        "density" => "kg/m³",
        "young_modulus" => "Pa",
        "velocity" | "pulse_speed" | "shock_speed" => "m/s",
        "viscosity" => "N·s/m",
        "frequency" => "Hz",
        "piston_work" | "energy_dissipated" => "J",
        "gravity" | "g" => "m/s²",
        "duration" | "t_contact" | "t_release" | "dt" | "t" | "t_end" | "every" => "s",
        "air_drag" => "1/s",
        "precompression" | "force" => "N",
        "pulse_width" => "beads",
        _ if base.starts_with("wall_") && base.ends_with("_peak_force") => "N",
        _ if base.starts_with("wall_") && base.ends_with("_impulse") => "N·s",
        _ if base.starts_with("arrival_") => "s",
        _ if base.starts_with("peak_v_") || base.starts_with("amplitude_") => "m/s",
        _ if base.starts_with("peak_f_") || base.starts_with("f_") => "N",
        _ if base.starts_with("v_") => "m/s",
        _ if base.starts_with("x_") => "m",
        _ => return None,
    })
}

/// An axis or colour-bar label: the column and its unit.
pub fn label(col: &str) -> String {
    match unit(col) {
        Some(u) => format!("{col} ({u})"),
        None => col.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_of_parameters_and_outcomes() {
        assert_eq!(label("mass[2]"), "mass[2] (kg)");
        assert_eq!(label("walls.precompression"), "walls.precompression (N)");
        assert_eq!(label("pattern.radius[1]"), "pattern.radius[1] (m)");
        assert_eq!(label("arrival_250"), "arrival_250 (s)");
        assert_eq!(label("wall_right_impulse"), "wall_right_impulse (N·s)");
        assert_eq!(label("f_wall_left"), "f_wall_left (N)");
        assert_eq!(label("damping.viscosity"), "damping.viscosity (N·s/m)");
        assert_eq!(label("drive.frequency"), "drive.frequency (Hz)");
        assert_eq!(label("piston.velocity"), "piston.velocity (m/s)");
        assert_eq!(label("amplitude_30"), "amplitude_30 (m/s)");
        assert_eq!(label("energy_dissipated"), "energy_dissipated (J)");
        for none in [
            "ejected",
            "energy_left",
            "fragments",
            "taper.ratio",
            "steps",
            "energy_error",
        ] {
            assert_eq!(unit(none), None, "{none}");
        }
    }
}
